"""``s2cl simulate``'s declared host memory on an image cube (:mod:`s2cl.app.cube_footprint`, what
:func:`s2cl.app.simulate_scene.cube_block_rows` sizes blocks with) against what a run really allocates: a generated
cube and an ENVI cube file simulated in blocks of a given number of rows in a child process, the growth of its peak
resident set (on a PoCL CPU device it holds the kernels' buffers too) and numpy's allocations as ``tracemalloc`` sees
them (:mod:`memory_probe`). Each run is simulated once before it is measured, with the same sizes: the kernels PoCL
builds for them, and the modules the quicklook loads, are then no part of the peak.

The margin: the declaration is not loose (resident set ≥ :data:`LOWEST` × declared) and undercounts by no more than
the allocator's and the libraries' own memory that numpy does not see (resident set ≤ :data:`HIGHEST` × declared;
numpy's peak ≤ declared). Resident ÷ declared when written, on both PoCL drivers: 0.92 (the generated cube with its
analysis, its quicklook the peak), 0.85 (without it, a block the peak), 0.74 and 0.77 (the cube files' blocks).
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from memory_probe import env as probe_env

from bench.bench_cube_footprint import PEAK_CHILD
from s2cl.io.budget import Budget

ROOT = Path(__file__).resolve().parents[1]
LOWEST, HIGHEST = 0.6, 1.1  # resident set / declared
#: the cube file's wavelengths (10 nm, float64)
WAVELENGTHS = np.arange(400.0, 2501.0, 10.0)
EFFECTS = "[effects]\natmosphere = true\nnoise = true\nquantise = true\ncalibrate = true\n"
ANALYSIS = '[analysis]\nkind = "igrm"\nparameter = "cab"\n'



def _generated(tmp_path: Path, device: str, rows: int, cols: int, analysis: bool) -> Path:
    toml = tmp_path / f"generated-{rows}x{cols}-{int(analysis)}.toml"
    toml.write_text(f'[scene]\nname = "g"\n[compute]\ndevice = "{device}"\n[surface]\n'
                    f'cube = "builtin:fields:{rows}x{cols}"\ngsd_m = 10\nquantity = "reflectance"\n{EFFECTS}'
                    f'correct = true\npsf = {{fwhm = 1.0}}\n{ANALYSIS if analysis else ""}')
    return toml


def _envi(tmp_path: Path, device: str, rows: int, cols: int, step_nm: int) -> Path:
    """An ENVI float64 cube of ``rows × cols`` pixels at :data:`WAVELENGTHS` (``step_nm`` 5: at the grid's 5 nm) and
    its scene (a 5 nm grid)."""
    wavelengths = WAVELENGTHS if step_nm == 10 else np.arange(400.0, 2501.0, step_nm)
    data = np.memmap(tmp_path / "cube.bip", dtype="<f8", mode="w+", shape=(rows, cols, wavelengths.size))
    shape = 0.05 + 0.4 / (1 + np.exp(-(wavelengths - 715) / 12))
    for r in range(rows):
        data[r] = np.linspace(0.5, 1.3, cols)[:, None] * shape * (1.0 + 0.1 * math.sin(r))
    data.flush()
    del data
    (tmp_path / "cube.hdr").write_text(
        f"ENVI\nsamples = {cols}\nlines = {rows}\nbands = {wavelengths.size}\nheader offset = 0\ndata type = 5\n"
        f"interleave = bip\nbyte order = 0\nwavelength = {{{', '.join(f'{w:g}' for w in wavelengths)}}}\n")
    toml = tmp_path / f"file-{step_nm}.toml"
    toml.write_text(f'[scene]\nname = "f"\n[compute]\ndevice = "{device}"\n[grid]\nstep_nm = 5\n[surface]\n'
                    f'cube = "cube.hdr"\ngsd_m = 10\nquantity = "reflectance"\n{EFFECTS}psf = true\n')
    return toml


def _declared(toml: Path, block: int, device_memory: bool) -> float:
    """The footprint's peak for blocks of ``block`` rows read with the halo (an upper bound of the rows read)."""
    from s2cl.app.chain_parts import scene_instrument
    from s2cl.app.checks import check_simulate
    from s2cl.app.cube_footprint import cube_footprint, samples_on_grid
    from s2cl.forward.reach import band_groups, cube_halo
    from s2cl.scene.scene import Scene

    checked = check_simulate(Scene.load(str(toml)), budget=Budget(10**11, "test"))
    sc, cube = checked.scene, checked.cube
    assert cube is not None
    halo = cube_halo(scene_instrument(sc), band_groups(sc.sensor, sc.spec.surface.gsd_m))
    bands = list(checked.analysis_bands) if checked.analysis is not None else []
    fp = cube_footprint(sc, cube.rows, cube.cols, cube.wavelengths, cube.interpolates, bands,
                        on_grid=samples_on_grid(cube), device_memory=device_memory)
    return fp.peak(min(cube.rows, block + 2 * halo))


def _measure(toml: Path, block: int) -> dict[str, float]:
    env = probe_env(MALLOC_MMAP_THRESHOLD_="131072")
    out = subprocess.run([sys.executable, "-c", PEAK_CHILD, str(toml), str(block)], capture_output=True, text=True,
                         env=env, cwd=toml.parent, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc peak resident set")
@pytest.mark.parametrize(("kind", "block"), [("generated with its analysis", 24), ("generated", 192),
                                             ("file, interpolated by the kernel", 96), ("file on the grid", 48)])
def test_a_cube_run_allocates_what_its_footprint_declares(rt, tmp_path: Path, kind: str, block: int) -> None:
    """A generated 480 × 480 image with the IGRM analysis in blocks of 24 rows (its quicklook the peak) and without
    it in blocks of 192 (a block the peak), and an ENVI float64 file of 240 × 240 pixels × 211 wavelengths (10 nm)
    in blocks of 96 rows on a 5 nm grid (the resampling kernel interpolates them), and one of 160 × 160 pixels × 421
    wavelengths at the grid's 5 nm in blocks of 48 rows: the run's growth in resident set within the stated margin
    of the declared peak, numpy's within it."""
    if kind.startswith("generated"):
        toml = _generated(tmp_path, rt.info.spec, 480, 480, "analysis" in kind)
    else:
        toml = _envi(tmp_path, rt.info.spec, 240, 240, 10) if "interpolated" in kind else _envi(
            tmp_path, rt.info.spec, 160, 160, 5)
    declared = _declared(toml, block, rt.host_memory)
    measured = _measure(toml, block)
    report = (f"{kind}, blocks of {block} rows on {rt.name}: resident {measured['rss'] / 1e6:.1f} MB, numpy "
              f"{measured['traced'] / 1e6:.1f} MB, against {declared / 1e6:.1f} MB declared "
              f"({measured['rss'] / declared:.2f})")
    print(report)
    assert measured["traced"] <= declared, report
    assert measured["rss"] <= HIGHEST * declared, report
    if rt.host_memory:  # the kernels' buffers are in the resident set
        assert measured["rss"] >= LOWEST * declared, report
