"""A library file's declared reading memory (:func:`s2cl.libraries.files.library_read_footprint`, what
:func:`~s2cl.libraries.files.require_library_memory` refuses with) against what reading one allocates: a CSV library
read onto a 1 nm grid in a child process, the growth of its peak resident set and numpy's peak
(:mod:`memory_probe`). The margin: measured ≥ :data:`LOWEST` × declared, and ≤ :data:`HIGHEST` × declared: the
declaration counts arrays, not the spectra's names (the header's and the library's Python strings, about 0.25 MB
here, 0.6 % of the declared 41.2 MB)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from memory_probe import env as probe_env

ROOT = Path(__file__).resolve().parents[1]
LOWEST, HIGHEST = 0.8, 1.02  # measured / declared
SPECTRA, WAVELENGTHS = 2000, np.arange(400.0, 2501.0, 10.0)

#: in a child process: read the library once (modules loaded), then again with the peak reset
_CHILD = r"""
import json, sys
from memory_probe import peak
from s2cl.grid import SpectralGrid
from s2cl.libraries.files import load_csv_library
grid = SpectralGrid(400.0, 2500.0, 1.0)
load_csv_library(sys.argv[1], grid)
print(json.dumps(peak(lambda: load_csv_library(sys.argv[1], grid))))
"""


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc peak resident set")
def test_reading_a_library_allocates_what_its_footprint_declares(tmp_path: Path) -> None:
    """2,000 spectra × 211 wavelengths (10 nm) read onto the 1 nm grid (2,101 values): the values as read (the
    reader's count: 211 rows × 2,001 columns × 8 bytes), the spectra on the grid (2,000 × 2,101 × 8 bytes) and their
    finiteness test (one block of 4,096 spectra at most: all 2,000, 1 byte a value)."""
    from s2cl.grid import SpectralGrid
    from s2cl.libraries.files import library_read_footprint

    values = 0.2 + 0.3 * np.random.default_rng(1).random((WAVELENGTHS.size, SPECTRA))
    path = tmp_path / "lib.csv"
    with path.open("w") as f:
        f.write("wavelength_nm," + ",".join(f"s{i}" for i in range(SPECTRA)) + "\n")
        for w, row in zip(WAVELENGTHS, values, strict=True):
            f.write(f"{w:g}," + ",".join(f"{v:.4f}" for v in row) + "\n")
    grid = SpectralGrid(400.0, 2500.0, 1.0)
    parts = library_read_footprint(SPECTRA, WAVELENGTHS.size * (SPECTRA + 1) * 8.0, grid)
    declared = sum(a.bytes(SPECTRA) for a in parts)
    assert declared == WAVELENGTHS.size * (SPECTRA + 1) * 8 + SPECTRA * 2101 * (8 + 1)  # by hand
    out = subprocess.run([sys.executable, "-c", _CHILD, str(path)], capture_output=True, text=True,
                         env=probe_env(MALLOC_MMAP_THRESHOLD_="131072"), cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    report = (f"resident {measured['rss'] / 1e6:.1f} MB, numpy {measured['traced'] / 1e6:.1f} MB, against "
              f"{declared / 1e6:.1f} MB declared")
    print(report)
    assert measured["rss"] <= HIGHEST * declared and measured["traced"] <= HIGHEST * declared, report
    assert max(measured["rss"], measured["traced"]) >= LOWEST * declared, report
