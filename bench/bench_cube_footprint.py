"""``s2cl simulate`` of an image: the declared host memory (:mod:`s2cl.app.cube_footprint`) against the measured peak
(growth of the resident set and numpy's traced peak, ``tests/memory_probe.py``, in a child process that simulates the
scene once to warm up and then again, measured), per OpenCL device, for a generated cube and two ENVI files, each in
blocks of two sizes: the peaks, and the bytes per input pixel of a row read (the difference of the two runs over the
rows between them).

    python -m bench.bench_cube_footprint                   # devices 0:0 and 1:0 (the two PoCL drivers)
    python -m bench.bench_cube_footprint --device 0:0

Writes ``bench/results/cube-footprint.json`` (the ``images.cube-footprint`` block of docs/images.md).
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import ROOT, load_average, machine_info, write_json

RESULT = "cube-footprint.json"
WAVELENGTHS_10NM = np.arange(400.0, 2501.0, 10.0)
EFFECTS = "[effects]\natmosphere = true\nnoise = true\nquantise = true\ncalibrate = true\n"
#: the cases: name, cube, blocks of rows measured (the smaller first)
CASES = (("generated 480 × 480, IGRM analysis", "generated-analysis", (24,)),
         ("generated 480 × 480", "generated", (48, 192)),
         ("ENVI float64 240 × 240 × 211 (10 nm), interpolated by the kernel", "envi-10nm", (24, 96)),
         ("ENVI float64 160 × 160 × 421 (5 nm), the grid's samples", "envi-5nm", (12, 48)))

#: in a child process (tests/ on its path, for memory_probe): simulate the scene with the block rule replaced by
#: ``block`` rows, once to warm up, then with the peak resident set reset and numpy's allocations traced; also the
#: footprint test's probe (tests/test_cube_footprint.py)
PEAK_CHILD = r"""
import json, sys, tempfile
from pathlib import Path
from memory_probe import peak
import s2cl.app.simulate_scene as simulate_scene
scene, block = sys.argv[1], int(sys.argv[2])
simulate_scene.footprint_block_rows = lambda *args, **kwargs: block
out = Path(tempfile.mkdtemp())
simulate_scene.simulate_scene(scene, out / "warm")
print(json.dumps(peak(lambda: simulate_scene.simulate_scene(scene, out / "run"))))
"""


def scene_file(folder: Path, kind: str, device: str) -> Path:
    """The scene of case ``kind`` on ``device`` (and its ENVI file) in ``folder``."""
    toml = folder / f"{kind}.toml"
    head = f'[scene]\nname = "{kind}"\n[compute]\ndevice = "{device}"\n'
    if kind.startswith("generated"):
        analysis = '[analysis]\nkind = "igrm"\nparameter = "cab"\n' if kind.endswith("analysis") else ""
        toml.write_text(f'{head}[surface]\ncube = "builtin:fields:480x480"\ngsd_m = 10\nquantity = "reflectance"\n'
                        f"{EFFECTS}correct = true\npsf = {{fwhm = 1.0}}\n{analysis}")
        return toml
    step = 10 if kind == "envi-10nm" else 5
    rows = cols = 240 if step == 10 else 160
    w = np.arange(400.0, 2501.0, step)
    data = np.memmap(folder / f"{kind}.bip", dtype="<f8", mode="w+", shape=(rows, cols, w.size))
    shape = 0.05 + 0.4 / (1 + np.exp(-(w - 715) / 12))
    for r in range(rows):
        data[r] = np.linspace(0.5, 1.3, cols)[:, None] * shape * (1.0 + 0.1 * math.sin(r))
    data.flush()
    del data
    (folder / f"{kind}.hdr").write_text(
        f"ENVI\nsamples = {cols}\nlines = {rows}\nbands = {w.size}\nheader offset = 0\ndata type = 5\n"
        f"interleave = bip\nbyte order = 0\nwavelength = {{{', '.join(f'{x:g}' for x in w)}}}\n")
    toml.write_text(f'{head}[grid]\nstep_nm = 5\n[surface]\ncube = "{kind}.hdr"\ngsd_m = 10\n'
                    f'quantity = "reflectance"\n{EFFECTS}psf = true\n')
    return toml


def declared(toml: Path, host_memory: bool) -> tuple[Any, int, int]:
    """The scene's footprint, its cube's columns and its blocks' halo."""
    from s2cl.app.chain_parts import scene_instrument
    from s2cl.app.checks import check_simulate
    from s2cl.app.cube_footprint import cube_footprint, samples_on_grid
    from s2cl.forward.reach import band_groups, cube_halo
    from s2cl.io.budget import Budget
    from s2cl.scene.scene import Scene

    checked = check_simulate(Scene.load(str(toml)), budget=Budget(10**11, "bench"))
    sc, cube = checked.scene, checked.cube
    assert cube is not None
    bands = list(checked.analysis_bands) if checked.analysis is not None else []
    fp = cube_footprint(sc, cube.rows, cube.cols, cube.wavelengths, cube.interpolates, bands,
                        on_grid=samples_on_grid(cube), device_memory=host_memory)
    return fp, cube.cols, cube_halo(scene_instrument(sc), band_groups(sc.sensor, sc.spec.surface.gsd_m))


def measure(toml: Path, block: int) -> dict[str, int]:
    """The child's peak resident-set growth and numpy's peak (bytes) for blocks of ``block`` rows."""
    import os

    path = os.pathsep.join([str(ROOT), str(ROOT / "tests"), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "PYTHONPATH": path, "MALLOC_MMAP_THRESHOLD_": "131072"}
    out = subprocess.run([sys.executable, "-c", PEAK_CHILD, str(toml), str(block)], capture_output=True, text=True,
                         env=env, cwd=toml.parent, timeout=900, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def run_device(spec: str) -> dict[str, Any]:
    from s2cl.cl.runtime import get_runtime

    rt = get_runtime(spec)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for title, kind, blocks in CASES:
            toml = scene_file(Path(tmp), kind, spec)
            fp, cols, halo = declared(toml, rt.host_memory)
            runs = []
            for block in blocks:
                m = measure(toml, block)
                runs.append({"block_rows": block, "declared": fp.peak(block + 2 * halo), "rss": m["rss"],
                             "traced": m["traced"]})
                print(f"{rt.name} {title}, {block} rows: {runs[-1]}", flush=True)
            row: dict[str, Any] = {"case": title, "cols": cols, "halo": halo, "runs": runs}
            if len(runs) == 2:  # bytes per input pixel of a row read: between the two block sizes
                pixels = (runs[1]["block_rows"] - runs[0]["block_rows"]) * cols
                row["per_pixel_row"] = {k: (runs[1][k] - runs[0][k]) / pixels for k in ("declared", "rss", "traced")}
            rows.append(row)
    return {"device": rt.name, "spec": spec, "cases": rows}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--device", action="append", help="OpenCL device (repeatable; default 0:0 and 1:0)")
    args = p.parse_args(argv)
    start = load_average()
    devices = [run_device(spec) for spec in (args.device or ["0:0", "1:0"])]
    write_json(RESULT, {"command": "python -m bench.bench_cube_footprint", "machine": machine_info(),
                        "load_average_start": start, "load_average_end": load_average(), "devices": devices})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
