"""Throughput of a product-sized scene: an EnMAP L2A product in its shipped layout (tests/product_fixtures.py;
PROSAIL parcels of ``builtin:fields`` put on EnMAP's 224 bands, int16) through ``s2cl simulate`` to all 13
Sentinel-2 bands and an IGRM map, against

(a) reading the product alone, by the same row blocks, through the same reader (``s2cl.io.cubes.open_cube``);
(b) the chain's resampling kernel alone (interpolation onto the grid, atmosphere and SRFs,
    :meth:`s2cl.forward.simulate.Simulator.band_radiance`) on the same pixels, as the chain gives them to it (the
    product's own bands, no-data pixels zeroed: :meth:`s2cl.forward.cube.SceneCube.block`, untimed).

The product's files are written through to disk (:func:`synced`) before anything is timed, and the three runs read
it from the page cache alike. The end-to-end run happens in a child process with the ``--max-memory`` given; its
peak resident memory (max RSS) is reported against it, with where the time went (self time of the chain's steps,
timers installed in the child).
Each of the three is run ``--repeat`` times, in turn, and its median kept (the machine is shared: one run of each
moves by tens of percent). Writes bench/results/product-<machine>-<date>.json; docs/images.md shows it
(``python -m bench.doc_blocks``).

    python -m bench.bench_product [--size 1000] [--max-memory 2G] [--keep DIR] [--repeat 3]
    python -m bench.bench_product --example          # the worked example of docs/images.md (120 x 120, --format cog)
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import ROOT, load_average, machine_info, write_result

SEED = 1
EXAMPLE_SIZE = 120
EXAMPLE_JSON = ROOT / "docs" / "images" / "enmap-example.json"
EXAMPLE_PNG = ROOT / "docs" / "images" / "enmap-example-quicklook.png"


def scene_toml(cube: str, fmt: str = "netcdf") -> str:
    """The scene of the example and of the benchmark: the product declared at 10 m (all 13 bands at their nominal
    factors; the outputs' map grids follow the product's 30 m pixels), IGRM Cab on B4 B5 B6 B7."""
    return f"""[scene]
name = "enmap-example"
description = "An EnMAP L2A product through the chain: all 13 bands, an IGRM map, on the product's map grid"

[surface]
cube = "{cube}"   # the product folder, as DLR ships it
gsd_m = 10                     # simulate all 13 bands at their nominal factors (the product's pixels are 30 m)
quantity = "reflectance"

[effects]
atmosphere = true
correct = true
seed = 1

[analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]

[output]
format = "{fmt}"
"""


def make_product(folder: Path, size: int) -> Path:
    """An EnMAP L2A product of ``size × size`` pixels in ``folder``: the parcels of ``builtin:fields:SIZExSIZE``
    (seed 1), each parcel's spectrum averaged over each EnMAP band's Gaussian response (its FWHM)."""
    sys.path.insert(0, str(ROOT / "tests"))
    import product_fixtures as pf

    from s2cl.grid import DEFAULT_GRID
    from s2cl.libraries.fields import fields_image

    image = fields_image(DEFAULT_GRID, size, size, SEED)
    wl, fwhm, _, _ = pf.enmap_wavelengths()
    g = DEFAULT_GRID.wavelengths
    weights = np.exp(-4 * np.log(2) * ((g[None, :] - wl[:, None]) / fwhm[:, None]) ** 2)
    weights /= weights.sum(axis=1, keepdims=True)
    bands = image.library.spectra @ weights.T  # (spectra, 224)
    labels = image.labels.reshape(size, size)
    path, _ = pf.write_enmap(folder, size, size, rho_rows=lambda r0, r1: bands[labels[r0:r1]],
                             empty_corner=max(7, size // 12))
    return path


def synced(folder: Path) -> None:
    """Every file under ``folder`` written through to disk (``fsync``) before anything is timed: a product just
    written is otherwise still being written back while the first run reads it (measured: the end-to-end run, first,
    read it in 2.2 s, reading alone, after it, in 0.86 s)."""
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            fd = os.open(p, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)


class StepTimers:
    """Self time of named steps (time in a step minus the time in the steps it calls), by wrapping functions."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self.calls: dict[str, int] = {}
        self._stack: list[list[float]] = []

    def wrap(self, owner: Any, attr: str, name: str) -> None:
        inner = getattr(owner, attr)

        def timed(*args: Any, **kwargs: Any) -> Any:
            self._stack.append([time.perf_counter(), 0.0])
            try:
                return inner(*args, **kwargs)
            finally:
                start, children = self._stack.pop()
                total = time.perf_counter() - start
                self.seconds[name] = self.seconds.get(name, 0.0) + total - children
                self.calls[name] = self.calls.get(name, 0) + 1
                if self._stack:
                    self._stack[-1][1] += total

        setattr(owner, attr, timed)


#: the chain's steps timed in the child: (module, owner attribute path, name)
STEPS = (
    ("s2cl.io.cubes", "CubeReader.read", "read the product (GeoTIFF rows, scale, no data)"),
    ("s2cl.forward.cube", "nodata_rows", "NODATA: finite check of every pixel read"),
    ("s2cl.forward.simulate", "Simulator.band_radiance", "resampling kernel (onto the grid, atmosphere, SRFs)"),
    ("s2cl.forward.cube", "_Group.add", "band images: box average, NODATA, store"),
    ("s2cl.forward.sense", "Sensing.__call__", "noise, DN, calibration, correction kernel"),
    ("s2cl.io.image_store", "NetcdfStore.write", "simulation.nc writes"),
    ("s2cl.app.image_analysis", "_Retrieval.add", "retrieval map (IGRM)"),  # by row blocks, as they are written
    ("s2cl.app.image_analysis", "_Retrieval.finish", "retrieval map (IGRM)"),
    ("s2cl.app.image_quicklook", "write_quicklook", "quicklook"),
)


def _install(timers: StepTimers) -> None:
    import importlib

    for module, path, name in STEPS:
        owner: Any = importlib.import_module(module)  # the chain looks these names up when it calls them
        parts = path.split(".")
        for part in parts[:-1]:
            owner = getattr(owner, part)
        timers.wrap(owner, parts[-1], name)


def child(scene: str, out: str, max_memory: str, fmt: str) -> dict[str, Any]:
    """The end-to-end run (``s2cl simulate``'s function) with step timers; its wall time, steps and max RSS."""
    timers = StepTimers()
    _install(timers)
    from s2cl.app.simulate_scene import simulate_scene

    t0 = time.perf_counter()
    run = simulate_scene(scene, out, max_memory=max_memory, fmt=fmt)
    seconds = time.perf_counter() - t0
    record = json.loads((Path(out) / "simulation.json").read_text())
    return {"seconds": seconds, "run_seconds": run.seconds, "pixels": run.pixels, "block_rows": record["block_rows"],
            "steps": timers.seconds, "calls": timers.calls,
            "max_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024,
            "written": [p.name for p in run.written], "warnings": record["warnings"]}


def _blocks(rows: int, block_rows: int | None) -> list[tuple[int, int]]:
    step = rows if not block_rows else block_rows
    return [(r, min(rows, r + step)) for r in range(0, rows, step)]


def read_alone(scene_path: Path, block_rows: int | None) -> float:
    """Seconds to read every row of the product through its reader, by the end-to-end run's blocks."""
    from s2cl.app.product_scene import scene_reader
    from s2cl.scene.scene import Scene

    reader = scene_reader(Scene.load(str(scene_path)))
    t0 = time.perf_counter()
    for r0, r1 in _blocks(reader.rows, block_rows):
        reader.read(r0, r1)
    return time.perf_counter() - t0


def kernel_alone(scene_path: Path, block_rows: int | None) -> float:
    """Seconds of the chain's resampling kernel on every pixel of the product, each block as the chain gives it to the
    kernel (read, no-data pixels zeroed: untimed)."""
    from s2cl.app.chain_parts import chain_parts
    from s2cl.app.product_scene import resolve_cube
    from s2cl.cl.runtime import get_runtime
    from s2cl.forward.cube import open_scene_cube
    from s2cl.forward.simulate import Simulator
    from s2cl.scene.scene import Scene

    scene, resolved = resolve_cube(Scene.load(str(scene_path)))  # the product opened once, as the run opens it
    assert resolved is not None
    parts = chain_parts(scene)  # the scene's atmosphere and correction, as the run's chain
    cube = open_scene_cube(resolved, parts)
    sim = Simulator.of(get_runtime(scene.run.device), parts, interpolation=cube.interpolation)
    kernel = 0.0
    for r0, r1 in _blocks(cube.rows, block_rows):
        spectra, _ = cube.block(r0, r1)
        t0 = time.perf_counter()
        sim.band_radiance(spectra)
        kernel += time.perf_counter() - t0
    return kernel


def run_child(scene: Path, out: Path, max_memory: str, fmt: str = "netcdf") -> dict[str, Any]:
    cmd = [sys.executable, "-m", "bench.bench_product", "--child", str(scene), str(out), max_memory, fmt]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    done = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT, env=env)
    if done.returncode != 0:
        raise RuntimeError(f"the end-to-end run failed:\n{done.stderr[-4000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def bench(size: int, max_memory: str, keep: Path | None, repeat: int = 3) -> dict[str, Any]:
    """The three runs, ``repeat`` times in turn (end to end, (a), (b), end to end, ...): each time is their median,
    the steps are those of the end-to-end run of median time, the memory peak the largest; every run's times kept."""
    from s2cl.cl.runtime import get_runtime
    from s2cl.io.budget import Budget

    machine = machine_info(get_runtime())  # its load average: before the runs
    work = Path(keep) if keep else Path(tempfile.mkdtemp(prefix="s2cl-bench-product-"))
    work.mkdir(parents=True, exist_ok=True)
    try:
        t0 = time.perf_counter()
        folder = work / "product"
        if not folder.exists():
            folder.mkdir()
            make_product(folder, size)
        synced(folder)
        made = time.perf_counter() - t0
        scene = work / "scene.toml"
        scene.write_text(scene_toml(f"product/{_name(folder)}"))
        out = work / "out"
        runs = []
        for _ in range(repeat):
            shutil.rmtree(out, ignore_errors=True)
            e2e = run_child(scene, out, max_memory)
            runs.append((e2e, read_alone(scene, e2e["block_rows"]), kernel_alone(scene, e2e["block_rows"])))
        samples = {"end_to_end_s": [e["seconds"] for e, _, _ in runs], "read_alone_s": [r for _, r, _ in runs],
                   "kernel_alone_s": [k for _, _, k in runs]}
        e2e = sorted((e for e, _, _ in runs), key=lambda e: e["seconds"])[(repeat - 1) // 2]
        read, kernel = statistics.median(samples["read_alone_s"]), statistics.median(samples["kernel_alone_s"])
        e2e_s = statistics.median(samples["end_to_end_s"])
        pixels = e2e["pixels"]
        steps = e2e["steps"]
        return {
            "machine": machine, "load_average_after": load_average(), "size": size, "bands": 224, "dtype": "int16",
            "product_bytes": sum(p.stat().st_size for p in (folder / _name(folder)).iterdir()),
            "max_memory": max_memory, "max_memory_bytes": Budget.of(max_memory).memory_bytes,
            "block_rows": e2e["block_rows"], "pixels": pixels,
            "end_to_end_s": e2e_s, "read_alone_s": read, "kernel_alone_s": kernel,
            "kernel_interpolates": True, "ratio_to_read_plus_kernel": e2e_s / (read + kernel),
            "pixels_per_s": {"end_to_end": pixels / e2e_s, "read_alone": pixels / read,
                             "kernel_alone": pixels / kernel},
            "repeats": repeat, "samples": samples,
            "ratios": [e["seconds"] / (r + k) for e, r, k in runs],
            "steps_s": steps, "step_calls": e2e["calls"],
            "other_s": e2e["seconds"] - sum(steps.values()),
            "max_rss_bytes": max(e["max_rss_bytes"] for e, _, _ in runs), "written": e2e["written"],
            "warnings": e2e["warnings"],
            "make_product_s": made,
        }
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)


def _name(folder: Path) -> str:
    """The product folder inside ``folder`` (named as DLR names it)."""
    return next(p.name for p in folder.iterdir() if p.is_dir())


def example() -> dict[str, Any]:
    """The worked example of docs/images.md: the product, the scene, ``s2cl simulate --format cog``, what it wrote
    read back with rasterio; the quicklook copied into docs/images/."""
    import rasterio

    work = Path(tempfile.mkdtemp(prefix="s2cl-example-"))
    try:
        folder = work / "product"
        folder.mkdir()
        make_product(folder, EXAMPLE_SIZE)
        name = _name(folder)
        scene = work / "enmap-example.toml"
        scene.write_text(scene_toml(f"product/{name}", "cog"))
        cli = [sys.executable, "-m", "s2cl", "simulate", scene.name, "-o", "out"]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
        done = subprocess.run(cli, capture_output=True, text=True, cwd=work, env=env)
        if done.returncode != 0:
            raise RuntimeError(done.stderr[-4000:])
        files = []
        for tif in sorted((work / "out").glob("*.tif")):
            with rasterio.open(tif) as src:
                files.append({"file": tif.name, "crs": src.crs.to_string() if src.crs else None,
                              "size": [src.width, src.height], "pixel_m": src.transform.a,
                              "corner": [src.transform.c, src.transform.f], "dtype": src.dtypes[0],
                              "nodata": None if src.nodata is None else str(src.nodata),
                              "bands": list(src.descriptions)})
        from s2cl.io.output import write_atomic, write_json

        write_atomic(EXAMPLE_PNG, lambda p: shutil.copyfile(work / "out" / "quicklook.png", p))
        record = json.loads((work / "out" / "simulation.json").read_text())
        warnings = [line for line in done.stderr.splitlines() if "WARNING" in line]  # not the progress bar
        result = {"size": EXAMPLE_SIZE, "scene": scene.read_text(), "command": " ".join(["s2cl", *cli[3:]]),
                  "stdout": done.stdout.strip(), "warnings": warnings, "files": files,
                  "analysis": {k: record["analysis"][k] for k in ("kind", "bands", "gsd_m", "pixels", "fitted_pixels",
                                                                  "invalid_pixels", "bound_pixels")},
                  "georeference": record["attrs"]["georeference"]}
        write_json(EXAMPLE_JSON, result)
        return result
    finally:
        shutil.rmtree(work, ignore_errors=True)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--size", type=int, default=1000, help="pixels a side (1000: an EnMAP-sized product)")
    p.add_argument("--max-memory", default="2G", help="the end-to-end run's --max-memory")
    p.add_argument("--keep", type=Path, help="work folder to keep (and reuse the product written there)")
    p.add_argument("--repeat", type=int, default=3, help="runs of each (end to end, (a), (b)) in turn; medians")
    p.add_argument("--example", action="store_true", help="the worked example of docs/images.md")
    p.add_argument("--child", nargs=4, metavar=("SCENE", "OUT", "MAX_MEMORY", "FORMAT"), help=argparse.SUPPRESS)
    a = p.parse_args(argv)
    if a.repeat < 1:
        p.error(f"--repeat must be at least 1, got {a.repeat}")
    if a.child:
        print(json.dumps(child(*a.child)))
        return
    if a.example:
        result = example()
        print(json.dumps({k: result[k] for k in ("files", "analysis")}, indent=1))
        return
    result = bench(a.size, a.max_memory, a.keep, a.repeat)
    path = write_result("product", result)
    print(json.dumps({k: v for k, v in result.items() if k != "machine"}, indent=1))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
