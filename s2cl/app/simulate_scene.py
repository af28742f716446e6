"""``s2cl simulate`` as a function: a scene checked, then streamed through the sensor chain into
``simulation.nc`` and ``simulation.json`` (or, for an image cube, simulated whole); what the command prints, as data."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from s2cl.scene.scene import Scene

SIMULATION_JSON = "simulation.json"

#: bytes per pixel of a cube: per input wavelength (float64 as loaded, and a working copy), per grid
#: wavelength (on the grid, TOA radiance, resampling input) and per band (images, noise, DN, calibration)
CUBE_BYTES_PER_INPUT, CUBE_BYTES_PER_GRID, CUBE_BYTES_PER_BAND = 16, 24, 48


@dataclass(frozen=True)
class SimulationRun:
    """A finished ``simulate``: the files ``written``; for a library scene also the per-band summary ``rows``,
    the NetCDF attributes ``attrs``, the scene's ``analysis`` (or None), ``pixels`` and ``seconds``."""

    scene: str
    folder: Path
    written: tuple[Path, ...]
    rows: list[dict[str, Any]] = field(default_factory=list)
    attrs: dict[str, Any] = field(default_factory=dict)
    analysis: dict[str, Any] | None = None
    pixels: int = 0
    seconds: float = 0.0


def simulate_scene(scene: str | Path | Scene = "default", out: str | Path | None = None, *,
                   device: str | None = None, max_memory: str | None = None,
                   progress: Callable[[int], None] | None = None,
                   on_start: Callable[[str, int], None] | None = None) -> SimulationRun:
    """Check ``scene`` (memory, disk, device and output folder included) before anything is created, then simulate
    it into ``out`` (default: the scene's output folder). ``on_start(label, total)`` is called once before the
    pixels stream, ``progress(n)`` as they do."""
    from s2cl.app.checks import check_simulate
    from s2cl.app.optimise import output_folder
    from s2cl.app.simulate import require_netcdf_disk, simulate_memory, simulate_to_netcdf
    from s2cl.cl.runtime import get_runtime
    from s2cl.io.budget import Budget
    from s2cl.io.outdir import check_output_dir, claim
    from s2cl.io.output import write_json
    from s2cl.scene.caveats import report

    budget = Budget.of(max_memory)
    sc = scene if isinstance(scene, Scene) else Scene.load(str(scene))
    folder, where = output_folder(sc, out)
    checked = check_simulate(sc, budget=budget)
    check_output_dir(folder, where=where)
    if sc.spec.surface.cube is not None:
        return _simulate_cube(checked, folder, device, budget, progress, on_start)
    simulate_memory(checked, budget)
    require_netcdf_disk(checked, folder)
    get_runtime(device or sc.run.device)  # a device that does not exist is refused before the folder is made
    warnings = report(checked.caveats)
    total = checked.library.size * sc.run.copies
    t0 = time.perf_counter()
    with claim(folder):
        if on_start:
            on_start(f"{sc.name}: {checked.library.size} spectra × {sc.run.copies}", total)
        result = simulate_to_netcdf(checked, folder / "simulation.nc", device=device, progress=progress)
        seconds = time.perf_counter() - t0
        write_json(folder / SIMULATION_JSON, {"scene": sc.name, "attrs": result.attrs, "pixels": total,
                                              "seconds": seconds, "stage_seconds": result.seconds,
                                              "bands": result.rows, "analysis": result.analysis,
                                              "warnings": warnings})
    return SimulationRun(sc.name, folder, (folder / "simulation.nc", folder / SIMULATION_JSON), result.rows,
                         result.attrs, result.analysis, total, seconds)


def _simulate_cube(checked: Any, folder: Path, device: str | None, budget: Any,
                   progress: Callable[[int], None] | None,
                   on_start: Callable[[str, int], None] | None) -> SimulationRun:
    """Simulate the scene's image cube (sized from its metadata, loaded whole and checked before the folder is
    made) into ``simulation.nc`` and ``simulation.json``; with an [analysis], its map goes into ``simulation.nc``
    and a quicklook into ``quicklook.png`` (:mod:`s2cl.app.image_analysis`)."""
    from s2cl.cl.runtime import get_runtime
    from s2cl.forward.cube import load_scene_cube, scene_cube_size, simulate_cube
    from s2cl.io.budget import BASELINE_BYTES
    from s2cl.io.outdir import claim
    from s2cl.io.output import write_json, write_netcdf
    from s2cl.scene.caveats import report

    sc = checked.scene
    pixels, wavelengths = scene_cube_size(sc)
    per_pixel = (CUBE_BYTES_PER_INPUT * wavelengths + (CUBE_BYTES_PER_GRID * sc.grid.size if wavelengths else 0)
                 + CUBE_BYTES_PER_BAND * sc.sensor.size)
    budget.require(BASELINE_BYTES + pixels * per_pixel, what=f"a cube of {pixels:,} pixels × {wavelengths} "
                   "wavelengths", key="surface.cube", source=sc.source, fits="crop the cube or coarsen grid.step_nm")
    rt = get_runtime(device or sc.run.device)
    cube = load_scene_cube(sc)
    warnings = report(checked.caveats)
    t0 = time.perf_counter()
    written = [folder / "simulation.nc", folder / SIMULATION_JSON]
    with claim(folder):
        if on_start:
            on_start(f"{sc.name}: cube", 1)
        ds = simulate_cube(rt, sc, cube=cube, progress=(lambda n: progress(1)) if progress else None)
        analysis = None
        if checked.analysis is not None:
            from s2cl.app.image_analysis import analyse_image
            from s2cl.app.image_quicklook import write_quicklook

            analysis = analyse_image(rt, sc, ds, cube, list(checked.analysis_bands), checked.analysis)
            written.append(write_quicklook(ds, folder / "quicklook.png", analysis["map"]))
        write_netcdf(folder / "simulation.nc", ds)
        seconds = time.perf_counter() - t0
        attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in ds.attrs.items()}
        write_json(folder / SIMULATION_JSON, {"scene": sc.name, "attrs": attrs, "pixels": pixels,
                                              "seconds": seconds, "analysis": analysis, "warnings": warnings})
    return SimulationRun(sc.name, folder, tuple(written), attrs=attrs, analysis=analysis, pixels=pixels,
                         seconds=seconds)
