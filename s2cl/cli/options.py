"""Options and checks that several commands share: help texts, ``-q``, the output folder, the device."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import click

DEVICE_HELP = ("OpenCL device: PLATFORM:DEVICE indices or part of its name (default: $PYOPENCL_CTX, "
               "else the PoCL CPU); see `s2cl devices`")
QUIET_HELP = "no progress bar, tables or notes: only results and the files written (warnings still show)"
MAX_MEMORY_HELP = ("memory the run may use, e.g. 8G, 512M or 16GiB (default: $S2CL_MAX_MEMORY, else 4G; never more "
                   "than 90 % of the memory available); a run that needs more is refused before it starts")


def quiet_option(f: Callable) -> Callable:
    """``--quiet/-q`` with the common help text."""
    return click.option("--quiet", "-q", is_flag=True, help=QUIET_HELP)(f)


def output_dir(sc: Any, output: Path | None) -> tuple[Path, str]:
    """The output folder of a scene's run and how it was chosen (for error messages)."""
    if output is not None:
        return output, "--output"
    if sc.spec.output.directory:
        return sc.output_dir, f"output.directory in {sc.source}"
    return sc.output_dir, f"scene.name in {sc.source}"


def runtime(device: str | None) -> Any:
    """The OpenCL runtime of ``device``; a device that does not exist, or cannot compile a kernel, is refused
    here, before any work."""
    from s2cl.cl.runtime import get_runtime

    rt = get_runtime(device)
    rt.check_builds()
    return rt
