"""Find and render the kernel templates in ``kernels/`` (Mako, strict).

Mako turns each template into a Python module before rendering it (about 30 ms a template, 0.2 s for a
simulation's kernels); those modules are kept in the user cache folder (``mako/`` of
:func:`s2cl.io.cache.cache_dir`), each named by a digest of its template's path and text and of Mako's version
(:func:`module_path`), so a process renders from the modules an earlier one wrote, and an edited or upgraded template
never meets a module of another text. Without a writable cache folder (none, or one that cannot be written) the
modules stay in memory, as before."""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path
from typing import Any

import mako
from mako.exceptions import text_error_template
from mako.lookup import TemplateLookup

from s2cl.errors import InputError, RenderError
from s2cl.io.cache import cache_dir
from s2cl.resources import kernel_dir

#: the lookup's options, which shape the compiled modules (part of their names)
OPTIONS: dict[str, Any] = {"strict_undefined": True, "input_encoding": "utf-8"}


def module_path(folder: Path, filename: str, uri: str) -> str:
    """Where Mako keeps the module of the template ``filename`` (its ``uri`` in the lookup): in ``folder``, named by
    the uri and a digest of the template's path, its text, Mako's version and the lookup's options."""
    key = hashlib.sha256(f"{mako.__version__}\0{sorted(OPTIONS.items())}\0{filename}\0".encode()
                         + Path(filename).read_bytes()).hexdigest()
    return str(folder / f"{uri.strip('/').replace('/', '_')}-{key[:24]}.py")


@cache
def _lookup(in_memory: bool = False) -> TemplateLookup:
    folder = None
    if not in_memory:
        try:
            folder = cache_dir("mako")
        except InputError:  # no cache folder: the modules are compiled in memory by each process
            folder = None
    return TemplateLookup(directories=[str(kernel_dir())], **OPTIONS,
                          modulename_callable=None if folder is None else (lambda f, u: module_path(folder, f, u)))


def _template(name: str) -> Any:
    """The template ``kernels/<name>``, its module from the cache folder; compiled in memory where the folder exists
    but cannot be written (a read-only or shared home)."""
    try:
        return _lookup().get_template(name)
    except OSError:
        return _lookup(in_memory=True).get_template(name)


def render(name: str, **variables: Any) -> str:
    """Render ``kernels/<name>`` with ``variables``; deterministic, so identical inputs give
    identical source (and hit the program cache).

    :raises RenderError: with Mako's traceback of the template when rendering fails.
    """
    try:
        return _template(name).render(**variables)
    except Exception as err:  # Mako raises many types; keep its rendered traceback
        raise RenderError(f"rendering kernels/{name} failed:\n{text_error_template().render()}") from err


def render_def(name: str, def_name: str, **variables: Any) -> str:
    """Render one ``<%def>`` of ``kernels/<name>`` (e.g. a stage's device functions, to test it alone)."""
    try:
        return _template(name).get_def(def_name).render(**variables)
    except Exception as err:  # Mako raises many types; keep its rendered traceback
        raise RenderError(f"rendering {def_name} of kernels/{name} failed:\n{text_error_template().render()}") from err


def include_options() -> list[str]:
    """Build options that let kernels ``#include "common/…"``."""
    return ["-I", str(kernel_dir())]
