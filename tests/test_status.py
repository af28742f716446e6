"""The status codes and pixel flags live in one header (kernels/common/s2_status.clh); the Python enums
mirror it, and every retrieval's own enum takes its values from the shared one."""

from __future__ import annotations

import re

from s2cl.resources import kernel_dir
from s2cl.retrieve.igrm import FitStatus
from s2cl.retrieve.sam import SamStatus
from s2cl.status import PixelFlag, Status


def _header() -> dict[str, int]:
    text = (kernel_dir() / "common" / "s2_status.clh").read_text()
    return {name: int(value) for name, value in re.findall(r"#define (S2_\w+) (\d+)", text)}


def test_python_enums_match_the_header() -> None:
    header = _header()
    codes = {k[len("S2_"):]: v for k, v in header.items() if not k.startswith("S2_FLAG_")}
    flags = {k[len("S2_FLAG_"):]: v for k, v in header.items() if k.startswith("S2_FLAG_")}
    assert codes == {s.name: int(s) for s in Status}  # canonical names only (aliases are skipped)
    assert flags == {f.name: int(f) for f in PixelFlag if f.name != "NONE"}


def test_retrieval_enums_use_the_shared_codes() -> None:
    assert FitStatus.CONVERGED == Status.OK and FitStatus.STALLED == Status.STALLED
    assert FitStatus.INVALID_INPUT == Status.INVALID and FitStatus.DEGENERATE == Status.DEGENERATE
    assert SamStatus.UNCLASSIFIED == Status.UNCLASSIFIED and SamStatus.ZERO_VECTOR == Status.DEGENERATE
    assert len(set(map(int, Status))) == len(list(Status))  # no two canonical names share a code
