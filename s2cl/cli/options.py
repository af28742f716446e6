"""Options that several commands share: help texts and ``-q``."""

from __future__ import annotations

from collections.abc import Callable

import click

DEVICE_HELP = ("OpenCL device: PLATFORM:DEVICE indices or part of its name (default: $PYOPENCL_CTX, "
               "else the PoCL CPU); see `s2cl devices`")
QUIET_HELP = "no progress bar, tables or notes: only results and the files written (warnings still show)"
MAX_MEMORY_HELP = ("memory the run may use, e.g. 8G, 512M or 16GiB (default: $S2CL_MAX_MEMORY, else 4G; never more "
                   "than 90 % of the memory available); a run that needs more is refused before it starts")


def quiet_option(f: Callable) -> Callable:
    """``--quiet/-q`` with the common help text."""
    return click.option("--quiet", "-q", is_flag=True, help=QUIET_HELP)(f)
