"""Find and render the kernel templates in ``kernels/`` (Mako, strict)."""

from __future__ import annotations

from functools import cache
from typing import Any

from mako.exceptions import text_error_template
from mako.lookup import TemplateLookup

from s2cl.errors import RenderError
from s2cl.resources import kernel_dir


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


def render_def(name: str, def_name: str, **variables: Any) -> str:
    """Render one ``<%def>`` of ``kernels/<name>`` (e.g. a stage's device functions, to test it alone)."""
    try:
        return _lookup().get_template(name).get_def(def_name).render(**variables)
    except Exception as err:  # Mako raises many types; keep its rendered traceback
        raise RenderError(f"rendering {def_name} of kernels/{name} failed:\n{text_error_template().render()}") from err


def include_options() -> list[str]:
    """Build options that let kernels ``#include "common/…"``."""
    return ["-I", str(kernel_dir())]
