"""``s2cl simulate``'s declared host memory on a library (:mod:`s2cl.app.simulate_footprint`, what
:func:`s2cl.app.simulate.simulate_memory` refuses with) against what a run really allocates: the default scene
streamed into NetCDF in a child process, its peak resident set (on a PoCL CPU device it holds the device's buffers
too) and numpy's allocations as ``tracemalloc`` sees them.

The margin: the declaration is an upper bound (measured ≤ declared) that is not loose (measured ≥ 0.7 × declared).
The child's large arrays are mapped and unmapped one by one (``MALLOC_MMAP_THRESHOLD_``): memory an earlier run freed
and the C allocator kept would otherwise hide a run's own growth.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
from memory_probe import env as probe_env

from s2cl.io.budget import Budget

ROOT = Path(__file__).resolve().parents[1]
LOWEST = 0.7  # measured / declared at least
BIG = Budget(10**11, "test")

#: in a child process: simulate the warm-up scene (kernels built, modules loaded), then the scene with the peak resident
#: set reset (VmHWM) and numpy's allocations traced
_CHILD = r"""
import json, sys, tempfile
from pathlib import Path
from memory_probe import peak
from s2cl.app.checks import check_simulate
from s2cl.app.simulate import simulate_to_netcdf
from s2cl.io.budget import Budget
from s2cl.scene.scene import Scene
device, scene, warm = sys.argv[1], sys.argv[2], sys.argv[3]
checked = check_simulate(Scene.load(scene), budget=Budget(10**11, "test"))
out = Path(tempfile.mkdtemp())
simulate_to_netcdf(check_simulate(Scene.load(warm), budget=Budget(10**11, "test")), out / "warm.nc", device=device)
print(json.dumps(peak(lambda: simulate_to_netcdf(checked, out / "run.nc", device=device))))
"""


def _scene(tmp_path: Path, copies: int, analysis: bool) -> Path:
    """The default scene with ``copies``, with or without its [analysis] (and [sweep], which names its bands)."""
    lines, keep = [], True
    for line in (ROOT / "scenes" / "default.toml").read_text().splitlines():
        if line.startswith("["):
            keep = analysis or not line.startswith(("[analysis", "[sweep"))
        if keep:
            lines.append(line)
    path = tmp_path / f"scene-{copies}-{int(analysis)}.toml"
    path.write_text(re.sub(r"(?m)^copies = \d+", f"copies = {copies}", "\n".join(lines) + "\n"))
    return path


def _measure(device: str, scene: Path, warm: Path) -> dict[str, float]:
    env = probe_env(MALLOC_MMAP_THRESHOLD_="131072")
    out = subprocess.run([sys.executable, "-c", _CHILD, device, str(scene), str(warm)], capture_output=True,
                         text=True, env=env, cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc peak resident set")
@pytest.mark.parametrize(("copies", "analysis"), [(1000, False), (8000, False), (8000, True),
                                                 pytest.param(40000, True, marks=pytest.mark.slow)])
def test_a_library_run_allocates_what_its_footprint_declares(rt, tmp_path: Path, copies: int, analysis: bool) -> None:
    """120 spectra × 1,000 copies (one chunk, one launch) and × 8,000 (one chunk of 960,000 pixels in two launches),
    13 bands, all stages, with and without the IGRM analysis (whose arrays are the peak at 40,000 copies, 4.8 million
    pixels, after five chunks): the run's growth in resident set within the declared peak (what a run holds before
    it, the library and the interpreter, left out), and at least 0.7 of it. The warm-up run has the scene's copies
    (the peak then counts no one-time cost) up to 8,000, 100 beyond."""
    from s2cl.app.checks import check_simulate
    from s2cl.app.simulate_footprint import simulate_footprint
    from s2cl.scene.scene import Scene

    path = _scene(tmp_path, copies, analysis)
    checked = check_simulate(Scene.load(str(path)), budget=BIG)
    assert (checked.analysis is not None) == analysis
    fp = simulate_footprint(checked, device_memory=rt.host_memory, baseline=False)
    declared = fp.peak - next(a.fixed for a in fp.held if a.name == "library (float64)")  # loaded before the run
    measured = _measure(rt.info.spec, path, path if copies <= 8000 else _scene(tmp_path, 100, analysis))
    report = (f"{copies} copies{' with the analysis' if analysis else ''} on {rt.name}: resident "
              f"{measured['rss'] / 1e6:.1f} MB, numpy {measured['traced'] / 1e6:.1f} MB, against {declared / 1e6:.1f} "
              "MB declared")
    print(report)
    assert measured["rss"] <= declared, report
    assert measured["traced"] <= declared, report
    if rt.host_memory:  # the device's buffers are in the resident set
        assert measured["rss"] >= LOWEST * declared, report


def test_a_chunk_is_no_larger_than_the_library() -> None:
    """120 spectra × 1,000 copies: one chunk of 120,000 pixels (``chunk_spectra`` alone would count 1,048 spectra,
    over 8 times the pixels); 10 × 10⁶ copies: one spectrum per chunk."""
    from s2cl.app.simulate_footprint import chunk_pixels, chunk_spectra

    assert chunk_spectra(1000) == 1048
    assert chunk_pixels(120, 1000) == 120 * 1000
    assert chunk_pixels(120, 8000) == 120 * 8000
    assert chunk_pixels(10, 10**6) == 10**6


def test_the_estimate_follows_the_pixels_not_the_chunk_rule(tmp_path: Path) -> None:
    """The old rule counted 1,048 spectra for 1,000 copies of 120 (as many pixels as 8,000 copies): the chunk's part
    of the estimate of 1,000 copies is now an eighth of that of 8,000, and a budget between the two refuses the larger
    only, in one line naming surface.copies."""
    from s2cl.app.checks import check_simulate
    from s2cl.app.simulate import simulate_memory
    from s2cl.errors import ResourceError
    from s2cl.scene.scene import Scene

    small = check_simulate(Scene.load(str(_scene(tmp_path, 1000, False))), budget=BIG)
    large = check_simulate(Scene.load(str(_scene(tmp_path, 8000, False))), budget=BIG)
    one = check_simulate(Scene.load(str(_scene(tmp_path, 1, False))), budget=BIG)
    a, b, fixed = simulate_memory(small, BIG), simulate_memory(large, BIG), simulate_memory(one, BIG)
    assert (a - fixed) < 0.2 * (b - fixed)
    budget = Budget(int((a + b) / 2), "test")
    simulate_memory(small, budget)
    with pytest.raises(ResourceError, match=r"surface\.copies") as err:
        simulate_memory(large, budget)
    assert "\n" not in str(err.value)


#: in a child process: ``s2cl.simulate`` of the scene and its Dataset once, then again with the peak resident set
#: reset and numpy's allocations traced
_IN_MEMORY_CHILD = r"""
import json, sys
from memory_probe import peak
from s2cl.app.library_simulation import simulate
from s2cl.scene.scene import Scene
device, scene = sys.argv[1], Scene.load(sys.argv[2])
simulate(scene, device=device).to_dataset()
print(json.dumps(peak(lambda: simulate(scene, device=device).to_dataset())))
"""


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc peak resident set")
@pytest.mark.parametrize("copies", [1000, 8000])
def test_an_in_memory_run_allocates_what_its_footprint_declares(rt, tmp_path: Path, copies: int) -> None:
    """``s2cl.simulate`` of 120 spectra × 1,000 and 8,000 copies (every pixel's outputs held) and its Dataset: the
    growth in resident set within the declared peak (the library, loaded before, left out), at least 0.7 of it."""
    from s2cl.app.simulate_footprint import in_memory_footprint
    from s2cl.scene.scene import Scene

    path = _scene(tmp_path, copies, False)
    fp = in_memory_footprint(Scene.load(str(path)), 120, device_memory=rt.host_memory, baseline=False)
    declared = fp.peak - next(a.fixed for a in fp.held if a.name == "library (float64)")
    env = probe_env(MALLOC_MMAP_THRESHOLD_="131072")
    out = subprocess.run([sys.executable, "-c", _IN_MEMORY_CHILD, rt.info.spec, str(path)], capture_output=True,
                         text=True, env=env, cwd=ROOT, timeout=600)
    assert out.returncode == 0, out.stderr[-3000:]
    measured = json.loads(out.stdout.strip().splitlines()[-1])
    report = (f"in memory, {copies} copies on {rt.name}: resident {measured['rss'] / 1e6:.1f} MB, numpy "
              f"{measured['traced'] / 1e6:.1f} MB, against {declared / 1e6:.1f} MB declared")
    print(report)
    assert measured["rss"] <= declared and measured["traced"] <= declared, report
    if rt.host_memory:  # the larger measure: with each chunk let go, freed pages keep the resident peak below numpy's
        assert max(measured["rss"], measured["traced"]) >= LOWEST * declared, report


def test_an_in_memory_run_too_large_is_refused_with_the_copies_that_fit(tmp_path: Path, monkeypatch) -> None:
    """Under a 200 MB limit 120 × 8,000 copies are refused in one line naming surface.copies and the most copies
    that fit, whose footprint fits (and one more copy's does not)."""
    from s2cl.app.library_simulation import simulate
    from s2cl.app.simulate_footprint import in_memory_footprint
    from s2cl.errors import ResourceError
    from s2cl.io.budget import BASELINE_BYTES
    from s2cl.scene.scene import Scene

    limit = int(BASELINE_BYTES + 200e6)
    monkeypatch.setenv("S2CL_MAX_MEMORY", str(limit))
    path = _scene(tmp_path, 8000, False)
    with pytest.raises(ResourceError, match=r"surface\.copies") as err:
        simulate(path)
    line = str(err.value)
    assert "\n" not in line and "in bounded memory" in line
    most = int(re.search(r"at most ([\d,]+) copies fit", line).group(1).replace(",", ""))
    scene = Scene.load(str(path))
    assert in_memory_footprint(scene, 120, copies=most).peak <= limit < in_memory_footprint(scene, 120,
                                                                                          copies=most + 1).peak


def test_a_chunk_is_let_go_before_the_next_is_sensed(tmp_path: Path, monkeypatch) -> None:
    """120 spectra × 1,000 copies in two chunks of 60 spectra: numpy's memory when the second chunk's sensing starts
    equals the first's (within 1 MB; one chunk's outputs are 11.7 MB), so a chunk never overlaps the next, as the
    footprint counts it (a chunk held by the loop or the generator overlapped the next before)."""
    import tracemalloc

    import s2cl.app.simulate as simulate_module
    import s2cl.app.simulate_footprint as footprint_module
    from s2cl.app.checks import check_simulate
    from s2cl.forward.simulate import Simulator
    from s2cl.scene.scene import Scene

    checked = check_simulate(Scene.load(str(_scene(tmp_path, 1000, analysis=False))), budget=Budget(10**11, "test"))
    monkeypatch.setattr(footprint_module, "SIMULATE_CHUNK_PIXELS", 60 * 1000)
    at_entry: list[int] = []
    real = Simulator.sense

    def sense(self, radiance, **kwargs):
        at_entry.append(tracemalloc.get_traced_memory()[0])
        return real(self, radiance, **kwargs)

    monkeypatch.setattr(Simulator, "sense", sense)
    tracemalloc.start()
    try:
        simulate_module.simulate_to_netcdf(checked, tmp_path / "out.nc")
    finally:
        tracemalloc.stop()
    assert len(at_entry) == 2
    assert abs(at_entry[1] - at_entry[0]) < 1e6, at_entry
