"""One-line errors made from the scene schema's validation problems: file, dotted key, what is allowed (the ranges
and choices declared in :mod:`s2cl.scene.schema`)."""

from __future__ import annotations

import difflib
import re
from typing import Any

from pydantic import ValidationError

from s2cl.errors import InputError, key_token, token
from s2cl.scene.schema import AnalysisSpec, SceneSpec


def input_error(err: ValidationError, source: str) -> InputError:
    """The first validation problem as one line: file, dotted key, what is allowed."""
    e = err.errors()[0]
    # a key that takes true/false or a table: pydantic names the union member tried in the location
    loc = [str(x) for x in e["loc"] if not (x == "bool" or "[" in str(x) or re.fullmatch(r"[A-Z]\w*Spec", str(x)))]
    if e["type"] in ("model_type", "bool_type") and len(loc) == 2 and loc[0] == "effects":
        return InputError(f"must be true, false or a table of the effect's settings, got {token(e.get('input'))}",
                          source=source, key=".".join(loc))
    if loc[:2] == ["analysis", "roles"]:  # role keys are written as keys of [analysis]
        loc = ["analysis", *loc[2:]]
    key = ".".join(key_token(x) for x in loc)
    if e["type"] == "extra_forbidden":
        allowed = _allowed_keys(loc[:-1])
        near = difflib.get_close_matches(loc[-1], allowed, n=1)
        hint = f" (did you mean {near[0]!r}?)" if near else ""
        return InputError(f"unknown key{hint}; allowed keys here: {', '.join(allowed)}", source=source, key=key)
    if e["type"] == "missing":
        return InputError("required key is missing", source=source, key=key)
    if e["type"] == "value_error":
        return InputError(str((e.get("ctx") or {}).get("error", e["msg"])), source=source, key=key)
    return InputError(f"{_allowed_text(e, loc)}, got {token(e.get('input'))}", source=source, key=key)


_BOUNDS = (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<"))


def _allowed_text(e: dict[str, Any], loc: list[str]) -> str:
    """'must be >= 1 and <= 16' from the field's declared range (not only the violated side)."""
    info = _field(loc)
    declared = []
    for meta in getattr(info, "metadata", []):
        for attr, sym in _BOUNDS:
            if getattr(meta, attr, None) is not None:
                declared.append(f"{sym} {getattr(meta, attr)}")
    ctx = e.get("ctx") or {}
    if declared and any(k in ctx for k, _ in _BOUNDS):
        return "must be " + " and ".join(declared)
    if "expected" in ctx:
        return f"must be one of {ctx['expected']}"
    return e["msg"].replace("Input should be", "must be")


def _field(loc: list[str]) -> Any:
    """The pydantic FieldInfo at a dotted location, or None."""
    info, _ = _walk(loc)
    return info


def _walk(loc: list[str]) -> tuple[Any, Any]:
    """(FieldInfo, type) at a dotted location; the type of an entry of a ``dict[str, Model]`` field (such as
    ``sweep.ranges.B4``) is the model, with no FieldInfo. (None, None) where the location leaves the schema."""
    model: Any = SceneSpec
    info = None
    for part in loc:
        model = _unwrap_optional(model)
        if getattr(model, "__origin__", None) is dict:  # an entry of a dict field: its key is the user's
            info, model = None, model.__args__[1]
            continue
        fields = getattr(model, "model_fields", None)
        if not fields or part not in fields:
            return None, None
        info = fields[part]
        model = info.annotation
    return info, model


def _allowed_keys(loc: list[str]) -> list[str]:
    if not loc:
        return list(SceneSpec.model_fields)
    if loc == ["analysis"]:
        return [k for k in AnalysisSpec.model_fields if k != "roles"] + ["an index's band roles (nir, swir, ...)"]
    _, model = _walk(loc)
    fields = getattr(_unwrap_optional(model), "model_fields", None)
    return list(fields) if fields else []


def _unwrap_optional(annotation: Any) -> Any:
    """``X | None`` → ``X``, ``Model | bool`` → ``Model`` (for walking nested sections)."""
    args = getattr(annotation, "__args__", None)
    if args and (type(None) in args or bool in args):
        rest = [a for a in args if a is not type(None) and a is not bool]
        if len(rest) == 1:
            return rest[0]
    return annotation
