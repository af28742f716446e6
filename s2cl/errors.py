"""Errors that s2cl raises on purpose.

Every error a user can cause derives from :class:`S2CLError`; the CLI prints it as one
line and exits non-zero. Messages name the file, the key and the allowed range.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

#: Longest piece of a file's content an error message may quote (characters).
TOKEN_LENGTH = 20


def token(value: object, limit: int = TOKEN_LENGTH) -> str:
    """A short, printable stand-in for a value read from a file, for error messages.

    Messages never echo file content beyond this: control characters become ``?``, anything longer
    than ``limit`` characters is cut with ``…``, strings are quoted (a user who pointed s2cl at the
    wrong file learns that it is the wrong file, not what it holds).
    """
    text = str(value) if isinstance(value, str) else repr(value)
    text = re.sub(r"[^\x20-\x7e\u00a0-\uffff]", "?", text)
    if len(text) > limit:
        text = text[: limit - 1] + "…"
    return repr(text) if isinstance(value, str) else text


def key_token(name: object) -> str:
    """A key or column name read from a file, for the ``KEY`` part of a message: as it is when it is a
    plain identifier (letters, digits, ``_ . -``, at most 40 characters), else :func:`token`."""
    text = str(name)
    return text if re.fullmatch(r"[A-Za-z0-9_.\-]{1,40}", text) else token(text)


class S2CLError(Exception):
    """Base class: an error with a message meant for the user, not a traceback."""


class InputError(S2CLError, ValueError):
    """Bad input: a file, a key or a value outside its allowed range.

    :param message: what is wrong and what is allowed.
    :param source: file (or object) the value came from, if any.
    :param key: dotted key or column name inside ``source``, if any.
    """

    def __init__(self, message: str, *, source: str | Path | None = None, key: str | None = None):
        self.source = str(source) if source is not None else None
        self.key = key
        self.detail = message
        where = ""
        if self.source and key:
            where = f"{self.source}: {key}: "
        elif self.source:
            where = f"{self.source}: "
        elif key:
            where = f"{key}: "
        super().__init__(where + message)

    def at(self, source: str | Path | None) -> InputError:
        """This error addressed to ``source`` (e.g. the scene file) where it names no file of its own."""
        return self if self.source or source is None else type(self)(self.detail, source=source, key=self.key)

    def within(self, source: str | Path, section: str) -> InputError:
        """The same error re-addressed to ``section.key`` of ``source`` (e.g. a scene file)."""
        key = f"{section}.{self.key}" if self.key else section
        return InputError(self.detail, source=source, key=key)


@contextmanager
def errors_in(source: str | Path | None) -> Iterator[None]:
    """Engines name the key of what is wrong; the application layer runs them inside this, which adds the file
    (the scene's) to an :class:`InputError` that names none."""
    try:
        yield
    except InputError as err:
        if err.source or source is None:
            raise
        raise err.at(source) from None


class DeviceError(S2CLError):
    """No OpenCL platform, or the requested device does not exist."""


class BuildError(S2CLError):
    """An OpenCL program failed to build.

    Carries what is needed to reproduce it: template, device, options, the build log and
    the path of the rendered source (so that the log's line numbers make sense).
    """

    def __init__(self, *, template: str, device: str, options: list[str], log: str, source_path: Path | None,
                 reason: str | None = None):
        self.template = template
        self.device = device
        self.options = list(options)
        self.log = log
        self.source_path = source_path
        self.reason = reason
        why = f" ({reason})" if reason else ""
        super().__init__(
            f"OpenCL build of {template} failed{why} on {device} (options: {' '.join(options) or 'none'}); "
            f"rendered source: {source_path or 'not kept (the cache folder cannot be written)'}\n{log}"
        )


class RenderError(S2CLError):
    """A kernel template failed to render (missing variable, syntax error)."""


class DependencyError(S2CLError):
    """An optional dependency is missing; the message says what to install."""


class OutputError(S2CLError):
    """An output cannot be written: folder not creatable, read-only, full, or in use by another run."""

    def __init__(self, message: str, *, path: str | Path):
        self.path = str(path)
        super().__init__(f"{self.path}: {message}")


class ResourceError(InputError):
    """A run would need more memory or disk than it may use; the key names what to lower."""
