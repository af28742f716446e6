"""The scene file reference (every section and key: type, default, allowed values, description) rendered as
Markdown from the schema's pydantic models. ``python -m s2cl.scene.reference_doc > docs/scenes.md`` writes the
committed page; ``tests/test_scene_reference.py`` fails when that page differs from :func:`render`.
"""

from __future__ import annotations

import json
import re
import types
from collections.abc import Iterator
from typing import Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel
from pydantic.fields import FieldInfo
from pydantic_core import PydanticUndefined

from s2cl.scene.schema import SceneSpec

#: pydantic constraint attribute -> symbol, as the "allowed" column shows it
_BOUNDS = (("ge", "≥"), ("gt", ">"), ("le", "≤"), ("lt", "<"))


def _strip_none(annotation: Any) -> tuple[Any, bool]:
    """``X | None`` → (X, True); anything else → (itself, False)."""
    args = get_args(annotation)
    if get_origin(annotation) in (Union, types.UnionType) and type(None) in args and len(args) == 2:
        return next(a for a in args if a is not type(None)), True
    return annotation, False


def _switch(annotation: Any) -> type[BaseModel] | None:
    """The settings' model of a key that takes ``true``/``false`` or a table of settings (``Model | bool``)."""
    args = get_args(annotation)
    if get_origin(annotation) in (Union, types.UnionType) and bool in args and len(args) == 2:
        model = next(a for a in args if a is not bool)
        return model if isinstance(model, type) and issubclass(model, BaseModel) else None
    return None


def _model(annotation: Any) -> type[BaseModel] | None:
    """The section model a field opens: its type, the value type of a ``dict[str, Model]``, the settings of a
    switch, or None."""
    inner, _ = _strip_none(annotation)
    if get_origin(inner) is dict:
        inner = get_args(inner)[1]
    elif get_origin(inner) is list:  # an array of tables ([[application]])
        inner = get_args(inner)[0]
    inner = _switch(inner) or inner
    return inner if isinstance(inner, type) and issubclass(inner, BaseModel) else None


def type_name(annotation: Any) -> str:
    """A short, TOML-minded name of a field's type (``float``, ``list of str``, ``table of str → str``)."""
    inner, optional = _strip_none(annotation)
    origin, args = get_origin(inner), get_args(inner)
    if _switch(inner) is not None:
        name = "bool or table"
    elif origin is Literal:
        name = "str" if all(isinstance(a, str) for a in args) else "choice"
    elif origin is list:
        name = f"list of {type_name(args[0])}"
    elif origin is dict:
        name = f"table of {type_name(args[0])} → {type_name(args[1])}"
    elif inner is Any:
        name = "any"
    elif isinstance(inner, type) and issubclass(inner, BaseModel):
        name = "table"
    else:
        name = getattr(inner, "__name__", str(inner))
    return f"{name} (optional)" if optional else name


def allowed(info: FieldInfo) -> str:
    """The values a field allows, from its declared bounds, lengths and ``Literal`` choices ('' when any)."""
    bounds = [(sym, getattr(m, a)) for m in info.metadata for a, sym in _BOUNDS if getattr(m, a, None) is not None]
    parts = [f"{sym} {int(v) if float(v).is_integer() else v}" for sym, v in bounds]  # 4294967295, not 4.29e+09
    parts += [f"at least {m.min_length} item(s)" if info.annotation is not str else "non-empty"
              for m in info.metadata if getattr(m, "min_length", None)]
    inner, _ = _strip_none(info.annotation)
    if get_origin(inner) is list:
        inner = get_args(inner)[0]
    if get_origin(inner) is Literal:
        parts.append("one of " + ", ".join(f"`{a}`" for a in get_args(inner)))
    return "; ".join(parts)


def default(info: FieldInfo) -> str:
    """A field's default as it would be written in TOML; 'required', or '—' for an unset optional key."""
    if info.default_factory is None and info.default is PydanticUndefined:
        return "required"
    value = info.default_factory() if info.default_factory else info.default  # type: ignore[call-arg]
    if value is None or isinstance(value, BaseModel):
        return "—" if value is None else "its defaults"
    return f"`{json.dumps(value, ensure_ascii=False, default=str)}`"


def _cell(text: str) -> str:
    """Text safe in a Markdown table cell: one line, no pipes, no HTML tags, reST roles as code."""
    text = re.sub(r":\w+:`([^`]+)`", r"`\1`", " ".join(text.split()))
    return re.sub(r"<(?=[A-Za-z])", "&lt;", text.replace("|", "\\|"))


def _key(prefix: str, name: str, info: FieldInfo) -> str:
    """The dotted table name a section field opens (``sweep.add``; ``sweep.ranges.KEY`` for a dict of them;
    ``[application]`` for an array of them, so that its heading reads ``[[application]]``)."""
    origin = get_origin(_strip_none(info.annotation)[0])
    return f"{prefix}{name}.KEY" if origin is dict else f"[{prefix}{name}]" if origin is list else f"{prefix}{name}"


def sections(model: type[BaseModel] = SceneSpec, prefix: str = "") -> Iterator[tuple[str, type[BaseModel], str]]:
    """(dotted TOML table name, its model, the description of its field) of every section, depth first."""
    for name, info in model.model_fields.items():
        sub = _model(info.annotation)
        if sub is not None:
            key = _key(prefix, name, info)
            yield key, sub, info.description or ""
            yield from sections(sub, f"{key.strip('[]')}.")


def undescribed(model: type[BaseModel] = SceneSpec) -> list[str]:
    """Dotted keys of every field, in every section, that has no description."""
    tables = [("", model), *((f"{key}.", sub) for key, sub, _ in sections(model))]
    return [f"{prefix}{name}" for prefix, sub in tables for name, info in sub.model_fields.items()
            if not (info.description or "").strip()]


def _table(model: type[BaseModel], prefix: str) -> list[str]:
    """The key table of one section (``prefix``: its dotted name and a dot; '' for the top level)."""
    lines = ["| key | type | default | allowed | description |", "|---|---|---|---|---|"]
    for name, info in model.model_fields.items():
        desc = info.description or ""
        if _model(info.annotation) is not None:
            key = _key(prefix, name, info)
            anchor = re.sub(r"[^\w-]", "", key).lower()  # the heading's anchor: punctuation dropped, lower case
            desc += f" (see [`[{key}]`](#{anchor}))"
        cells = (f"`{name}`", type_name(info.annotation), default(info), allowed(info), desc)
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    return [*lines, ""]


def render() -> str:
    """The whole reference page, Markdown."""
    lines = ["# Scene reference", "",
             "Every section and key of a scene file, generated from the schema that checks scenes "
             "(`s2cl/scene/schema.py`) by `python -m s2cl.scene.reference_doc > docs/scenes.md`; a test fails "
             "when this page is stale. `scenes/default.toml` shows the keys in use and the "
             "[guide](guide.md#scenes) how they fit together. A key left out takes its default; '—' marks an "
             "optional key left unset (its description says what that means); a scene with an unknown key, or "
             "a value outside the allowed range, is refused in one line.", "",
             "## Sections", "", *_table(SceneSpec, "")]
    for key, model, description in sections():
        doc = " ".join((model.__doc__ or "").split())
        intro = [description[:1].upper() + description[1:] + "."] if description else []
        if doc:  # the model's docstring, after the field's description unless it says the same
            intro = [*intro, doc] if not doc.lower().startswith(description.lower()) else [doc]
        lines += [f"## `[{key}]`", "", *(f"{_cell(t)}\n" for t in intro), *_table(model, f"{key.strip('[]')}.")]
    return "\n".join(lines)


if __name__ == "__main__":
    print(render())
