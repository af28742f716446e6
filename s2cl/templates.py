"""Find and render the kernel templates in ``kernels/`` (Mako, strict)."""

from __future__ import annotations

import importlib.resources
from functools import cache
from pathlib import Path
from typing import Any

from mako.exceptions import text_error_template
from mako.lookup import TemplateLookup

from .errors import RenderError


@cache
def kernel_dir() -> Path:
    """Directory of the OpenCL sources.

    In an installed wheel they sit inside the package (``s2cl/kernels``, found through
    :mod:`importlib.resources`); in a source checkout or editable install they are the
    top-level ``kernels/`` next to the package. Never relative to the working directory.
    """
    candidates = [
        Path(str(importlib.resources.files("s2cl") / "kernels")),
        Path(__file__).resolve().parent.parent / "kernels",
    ]
    for path in candidates:
        if (path / "common").is_dir():
            return path
    raise RenderError("s2cl's kernel sources are missing; looked in " + ", ".join(str(p) for p in candidates))


@cache
def _lookup() -> TemplateLookup:
    return TemplateLookup(directories=[str(kernel_dir())], strict_undefined=True, input_encoding="utf-8")


def render(name: str, **variables: Any) -> str:
    """Render ``kernels/<name>`` with ``variables``; deterministic, so identical inputs give
    identical source (and hit the program cache).

    :raises RenderError: with Mako's traceback of the template when rendering fails.
    """
    try:
        template = _lookup().get_template(name)
        return template.render(**variables)
    except Exception as err:  # Mako raises many types; keep its rendered traceback
        raise RenderError(f"rendering kernels/{name} failed:\n{text_error_template().render()}") from err


def include_options() -> list[str]:
    """Build options that let kernels ``#include "common/…"``."""
    return ["-I", str(kernel_dir())]
