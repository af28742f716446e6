"""Kernel builds that never print: the compiler's output is captured (file descriptor 2 included) and
becomes a DEBUG record or part of a :class:`~s2cl.errors.BuildError`; failing sources are kept in the
user cache folder (``failed-builds/`` of :func:`s2cl.io.cache.cache_dir`), never beside the user's files.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import sys
import tempfile
import threading
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from s2cl.errors import InputError, S2CLError
from s2cl.io.cache import cache_dir

#: ``S2CL_BUILD_WARNINGS=error`` turns a kernel build with compiler warnings into a :class:`BuildError`
#: (the test suite sets it); otherwise build logs are DEBUG records and never reach the terminal.
STRICT_ENV = "S2CL_BUILD_WARNINGS"


#: PoCL's kernel cache folder; s2cl points it into its own user cache folder unless the user set it
POCL_CACHE_ENV = "POCL_CACHE_DIR"


def pyopencl() -> Any:
    """pyopencl, imported on first use, with PoCL's kernel cache in s2cl's user cache folder
    (:func:`pocl_cache_dir`): the second process that builds a kernel finds it there."""
    if POCL_CACHE_ENV not in os.environ:
        try:
            os.environ[POCL_CACHE_ENV] = str(pocl_cache_dir())
        except InputError:  # s2cl's cache folder cannot be made: PoCL keeps its own (s2cl.cl.devices names why)
            pass
    import pyopencl

    return pyopencl


def pocl_cache_dir() -> Path:
    """Where PoCL keeps compiled kernels: ``$POCL_CACHE_DIR`` when set, else ``pocl/`` in s2cl's user
    cache folder (:func:`s2cl.io.cache.cache_dir`; ``$S2CL_CACHE`` moves both). PoCL keys each entry
    by device, source and build options."""
    if os.environ.get(POCL_CACHE_ENV):
        return Path(os.environ[POCL_CACHE_ENV])

    return cache_dir("pocl")


_STDERR_LOCK = threading.Lock()


@contextmanager
def _stderr_captured() -> Iterator[Callable[[], str]]:
    """Redirect file descriptor 2 into a temporary file for the duration; yields a function that
    returns what was written. PoCL's clang prints "N warnings generated." straight to fd 2."""
    with _STDERR_LOCK, tempfile.TemporaryFile() as tmp:
        sys.stderr.flush()
        saved = os.dup(2)
        os.dup2(tmp.fileno(), 2)
        try:
            yield lambda: (tmp.seek(0), tmp.read().decode("utf-8", "replace"))[1]
        finally:
            os.dup2(saved, 2)
            os.close(saved)


def quiet_build(build: Callable[[], Any], device: Any) -> tuple[Any, str, Exception | None]:
    """Run ``build`` with the compiler's output captured: (program or None, log, error or None).

    The log is the device's build log, plus whatever the compiler wrote to stderr when the log is
    empty; pyopencl's ``CompilerWarning`` (which only says that a log exists) is not shown.
    """
    cl_ = pyopencl()
    program, err = None, None
    with _stderr_captured() as printed, warnings.catch_warnings():
        warnings.simplefilter("ignore", cl_.CompilerWarning)
        try:
            program = build()
        except cl_.Error as exc:
            err = exc
        stderr_text = printed()
    if err is not None:
        return None, str(err).strip() or stderr_text.strip(), err
    try:
        log = program.get_build_info(device, cl_.program_build_info.LOG) or ""
    except cl_.Error:  # some drivers cannot report it
        log = ""
    log = log.strip() or stderr_text.strip()
    if "warning" in log.lower():
        keep_context_until_exit(program)
    return program, log, None


_KEPT: list[Any] = []


def keep_context_until_exit(program: Any) -> None:
    """Never release the OpenCL context of ``program``, a build that warned.

    The wheel's PoCL 3.0 (LLVM 14) leaks a reference to the build's IR when it takes a program from its kernel
    cache whose build warned that a vector argument "changes the ABI" (a width its code target lacks):
    releasing that context later, at any time and at the latest when the interpreter exits, aborts the process
    ("still have references to IRs - can't release LLVM context !", status 134) after all its work is done.
    The context is kept with one extra Python reference that nothing drops, so it is never released; other
    warnings are kept too (one small context per warning build, once per process), as a build's log cannot
    tell which ones leak.
    """
    context = program.get_info(pyopencl().program_info.CONTEXT)
    if any(context == kept for kept in _KEPT):
        return
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(context))  # interpreter shutdown frees what a list holds
    _KEPT.append(context)


FAILED_BUILDS = "failed-builds"


def save_source(source: str, template: str) -> Path | None:
    """Keep a rendered source that failed to build in the user cache folder (``failed-builds/``) and
    return its path; None when the cache cannot be written (the source is then in the DEBUG log)."""
    digest = hashlib.sha1(source.encode()).hexdigest()[:12]
    stem = Path(template).name.replace(".cl.mako", "").replace(".cl", "")
    try:
        path = cache_dir(FAILED_BUILDS) / f"{stem}-{digest}.cl"
        path.write_text(source, encoding="utf-8")
    except (OSError, S2CLError):
        return None
    return path
