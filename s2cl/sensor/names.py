"""Band names: one rule for every band a sensor or SRF table names.

A band name goes into output file names (``heatmap_B4.png``), NetCDF variable names (``radiance_B4``),
table headers and plots, so it is held to what is safe in all of them: 1-32 ASCII letters, digits, ``_`` or
``-``, starting with a letter or digit (``B8a``, ``B12``, ``swir-1``). Path separators, ``..``, spaces,
control characters and escape sequences are refused where the sensor or SRF table is read.
"""

from __future__ import annotations

import re
from pathlib import Path

from s2cl.errors import InputError, token

BAND_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,31}")
BAND_NAME_RULE = "1-32 letters, digits, '_' or '-', starting with a letter or digit"


def check_band_name(name: str, *, source: str | Path | None = None, key: str | None = None,
                    where: str = "") -> str:
    """``name`` when it follows :data:`BAND_NAME`, else :class:`InputError` quoting it (sanitised).

    :param where: where the name was read (``"line 5"``), put before the message.
    """
    if BAND_NAME.fullmatch(name):
        return name
    at = f"{where}: " if where else ""
    raise InputError(f"{at}band name {token(name)} is not allowed: a band name is {BAND_NAME_RULE}",
                     source=source, key=key)


def safe_file_part(name: str) -> str:
    """``name`` for use inside a file name: every character outside ``[A-Za-z0-9_-]`` becomes ``_``.
    Band names are checked where they are read (:func:`check_band_name`); this is the second line of
    defence for output files named after a band (``heatmap_NAME.png``): the result never holds a path
    separator, so the file stays in its folder."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", name)[:64] or "_"
