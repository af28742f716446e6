"""Input files and the values read from them, checked the same way by every reader.

:func:`input_file` is the one check every reader makes before it opens a file: the path names a regular
file (a FIFO would block the reader forever, a device such as ``/dev/zero`` never ends, a folder is not a
file). :func:`parse_number` reads a number from a text cell strictly: Python's ``float()`` also takes
``0_1`` (digit grouping: 1.0) and non-ASCII digits (``٠.١``), which no CSV file means as numbers.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

from s2cl.errors import InputError, token

#: a number as CSV files write them: optional sign, digits with an optional fraction, optional exponent;
#: or inf / nan (refused later, with a message naming the value, by the checks of finite values)
_NUMBER = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?|[+-]?(?:inf|infinity|nan)",
                     re.IGNORECASE)


def parse_number(text: str) -> float:
    """``text`` (already stripped) as a float, accepting only ASCII decimal notation.

    :raises ValueError: ``text`` is not a number in that notation (the caller names file, line and column).
    """
    if not _NUMBER.fullmatch(text):
        raise ValueError(f"not a number: {text!r}")
    return float(text)


def number_at(text: object, *, source: str | Path, key: str) -> float:
    """The number a file's metadata holds at ``key`` (header field, XML node, tag; :func:`parse_number`'s notation,
    surrounding space ignored), or one :class:`InputError` naming the file and key."""
    cell = str(text).strip()
    try:
        return parse_number(cell)
    except ValueError:
        raise InputError(f"must be a number, got {token(cell)}", source=source, key=key) from None


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a regular file"


def input_file(path: str | Path, *, what: str = "file", source: str | Path | None = None,
               key: str | None = None) -> Path:
    """``path`` when it names an existing regular file (symbolic links followed), else :class:`InputError`.

    :param what: what the file should be, for the message (``"spectral library file"``).
    :param source: the file that named ``path`` (a scene): the error is then addressed to ``source: key``
        and quotes ``path``; without it, to ``path`` itself.
    :param key: the key of ``source`` that named ``path`` (``surface.library``, ``sensor.srf``).
    """
    p = Path(path)
    try:
        mode = p.stat().st_mode
    except FileNotFoundError:
        reason = "not found"
    except NotADirectoryError:
        reason = "not found (a part of the path is not a folder)"
    except OSError as err:
        reason = f"cannot be read ({os.strerror(err.errno) if err.errno else type(err).__name__})"
    else:
        if stat.S_ISREG(mode):
            return p
        reason = f"is {_kind(mode)}, not a regular file"
    if source is not None:
        raise InputError(f"{what} {p} {reason}", source=source, key=key)
    raise InputError(f"{what} {reason}", source=p)
