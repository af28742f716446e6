"""Options and checks that several commands share: help texts, ``-q``, the Dask scheduler address."""

from __future__ import annotations

import re
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


#: a Dask scheduler address: [PROTOCOL://]HOST:PORT, HOST a name, an IPv4 address or an [IPv6] address
_SCHEDULER = re.compile(r"(?:(?P<protocol>[a-z][a-z0-9+.-]*)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+)"
                        r":(?P<port>[0-9]{1,5})")
SCHEDULER_PROTOCOLS = ("tcp", "tls", "ws", "wss", "ucx")


def check_scheduler(address: str) -> str:
    """``address`` when it has the form of a Dask scheduler address (``tcp://HOST:PORT`` or ``HOST:PORT``),
    else a one-line :class:`~s2cl.errors.InputError` naming ``--scheduler``; checked before anything is
    created (whether it answers: :func:`s2cl.sweep.engine.reach_scheduler`)."""
    from s2cl.errors import InputError, token

    m = _SCHEDULER.fullmatch(address.strip())
    if m is None or not 1 <= int(m["port"]) <= 65535 or (m["protocol"] or "tcp") not in SCHEDULER_PROTOCOLS:
        raise InputError(f"{token(address, 60)} is not a scheduler address: give [PROTOCOL://]HOST:PORT with PORT in "
                         f"1-65535 and PROTOCOL one of {', '.join(SCHEDULER_PROTOCOLS)} (e.g. tcp://10.0.0.5:8786)",
                         key="--scheduler")
    return address.strip()
