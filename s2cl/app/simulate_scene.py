"""``s2cl simulate`` as a function: a scene checked, then streamed through the sensor chain into
``simulation.nc`` and ``simulation.json`` (an image cube by blocks of rows); what the command prints, as data."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from s2cl.app.chain_parts import checked_parts, scene_instrument
from s2cl.app.checks import Checked, check_simulate
from s2cl.app.cube_footprint import (
    CubeFootprint,
    block_rows_fitting,
    cube_disk_bytes,
    cube_footprint,
    samples_on_grid,
)
from s2cl.app.image_analysis import StreamedAnalysis
from s2cl.app.image_quicklook import write_quicklook
from s2cl.app.optimise import output_folder
from s2cl.app.simulate import require_device_launches, require_netcdf_disk, simulate_memory, simulate_to_netcdf
from s2cl.app.simulate_footprint import total
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError, errors_in
from s2cl.forward.cube import open_scene_cube, simulate_cube
from s2cl.forward.reach import band_groups, cube_halo
from s2cl.io.budget import BASELINE_BYTES, Budget
from s2cl.io.cog import write_cogs
from s2cl.io.outdir import check_output_dir, claim
from s2cl.io.output import require_free, write_json
from s2cl.io.products.geotiff import rasterio_module
from s2cl.io.simulation_file import SIMULATION_NC, simulation_file
from s2cl.scene.caveats import report
from s2cl.scene.scene import Scene

SIMULATION_JSON = "simulation.json"


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
                   on_start: Callable[[str, int], None] | None = None, fmt: str | None = None) -> SimulationRun:
    """Check ``scene`` (memory, disk, device and output folder included) before anything is created, then simulate
    it into ``out`` (default: the scene's output folder). ``on_start(label, total)`` is called once before the
    pixels stream, ``progress(n)`` as they do. ``fmt``: ``netcdf`` or ``cog`` (also Cloud-Optimised GeoTIFFs of an
    image, :mod:`s2cl.io.cog`); default the scene's ``output.format``."""
    budget = Budget.of(max_memory)
    sc = scene if isinstance(scene, Scene) else Scene.load(str(scene))
    folder, where = output_folder(sc, out)
    cog = _cog_format(sc, fmt)
    checked = check_simulate(sc, budget=budget)  # a cube file's metadata opened once: the scene completed from it
    sc = checked.scene
    check_output_dir(folder, where=where)
    if checked.cube is not None:
        return _simulate_cube(checked, folder, device, budget, progress, on_start, cog)
    # a device that does not exist, or cannot hold one launch, is refused before the folder is made; its buffers are
    # the host's memory where it works in it (PoCL's CPU devices)
    rt = get_runtime(device or sc.run.device)
    simulate_memory(checked, budget, device_memory=rt.host_memory)
    require_netcdf_disk(checked, folder)
    require_device_launches(rt, sc)
    warnings = report(checked.caveats)
    total = checked.library.size * sc.run.copies
    t0 = time.perf_counter()
    with claim(folder):
        if on_start:
            on_start(f"{sc.name}: {checked.library.size} spectra × {sc.run.copies}", total)
        result = simulate_to_netcdf(checked, folder / SIMULATION_NC, device=device, progress=progress)
        seconds = time.perf_counter() - t0
        write_json(folder / SIMULATION_JSON, {"scene": sc.name, "attrs": result.attrs, "pixels": total,
                                              "seconds": seconds, "stage_seconds": result.seconds,
                                              "bands": result.rows, "analysis": result.analysis,
                                              "warnings": warnings})
    return SimulationRun(sc.name, folder, (folder / SIMULATION_NC, folder / SIMULATION_JSON), result.rows,
                         result.attrs, result.analysis, total, seconds)


def _cog_format(sc: Scene, fmt: str | None) -> bool:
    """Whether the run writes COGs (``fmt``, else ``output.format``), checked: an image scene, the geo extra."""
    fmt = fmt or sc.spec.output.format
    if fmt not in ("netcdf", "cog"):
        raise InputError(f"must be 'netcdf' or 'cog', got {fmt!r}", key="--format")
    if fmt != "cog":
        return False
    if sc.spec.surface.cube is None:
        raise InputError("'cog' writes GeoTIFFs of an image; a library scene has none (simulation.nc holds its "
                         "pixels)", source=sc.source, key="output.format")

    rasterio_module()  # the geo extra, before anything is created
    return True


def cube_block_rows(sc: Scene, budget: Any, rows: int, cols: int, wavelengths: int = 0,
                    interpolated: bool = False, analysis_bands: list[str] | tuple[str, ...] = (), *,
                    on_grid: bool = False, device_memory: bool = True) -> int | None:
    """Input rows of the scene's ``rows × cols`` cube (``wavelengths`` per pixel in its file; 0: generated)
    simulated at a time within ``budget`` (None: the whole image fits); a :class:`ResourceError` naming
    ``surface.cube`` when not even one block of rows fits. ``interpolated``: the resampling kernel puts the file's
    own bands on the grid (:attr:`s2cl.forward.parts.ResolvedCube.interpolates`), so no spectra on the grid are held,
    nor where they are the grid's (``on_grid``); ``analysis_bands``: the bands of the scene's analysis (none: no
    analysis); ``device_memory``: the kernels' buffers are the host's.

    The run's peak is its footprint (:func:`s2cl.app.cube_footprint.cube_footprint`: what it holds whole, and the
    larger of a block of rows read with the halo of its spatial filters, [spatial] PSF and [instrument] MTF and
    shift: :func:`s2cl.forward.reach.cube_halo`, the block reader's own, and the analysis' finish or the quicklook)
    beside :data:`~s2cl.io.budget.BASELINE_BYTES`."""
    fp = cube_footprint(sc, rows, cols, wavelengths, interpolated, analysis_bands, on_grid=on_grid,
                        device_memory=device_memory)
    return footprint_block_rows(sc, budget, fp, rows, cols, wavelengths)


def footprint_block_rows(sc: Scene, budget: Any, fp: CubeFootprint, rows: int, cols: int,
                         wavelengths: int) -> int | None:
    """:func:`cube_block_rows` of the footprint ``fp`` of the scene's ``rows × cols`` cube."""
    with errors_in(sc.source):
        groups = band_groups(sc.sensor, sc.spec.surface.gsd_m)
        halo = cube_halo(scene_instrument(sc), groups)
    unit = math.lcm(*[factor for factor, _ in groups])
    room = budget.memory_bytes - BASELINE_BYTES
    if fp.peak(rows + 2 * halo) <= room:
        return None
    budget.require(BASELINE_BYTES + fp.peak(unit + 2 * halo), what=f"a cube of {rows * cols:,} pixels × "
                   f"{wavelengths} wavelengths in blocks of {unit} rows", key="surface.cube", source=sc.source,
                   fits="crop the cube or coarsen grid.step_nm")
    return block_rows_fitting(fp, room, unit, halo, rows)


def _simulate_cube(checked: Checked, folder: Path, device: str | None, budget: Any,
                   progress: Callable[[int], None] | None,
                   on_start: Callable[[str, int], None] | None, cog: bool = False) -> SimulationRun:
    """Simulate the scene's image cube (sized from its metadata, checked before the folder is made) into
    ``simulation.nc``, row block by row block within ``budget`` (:func:`cube_block_rows`), and ``simulation.json``;
    with an [analysis], its map goes into ``simulation.nc`` and a quicklook into ``quicklook.png``
    (:mod:`s2cl.app.image_analysis`); with ``cog``, the GSD groups and the maps as COGs (:mod:`s2cl.io.cog`)."""
    sc, resolved = checked.scene, checked.cube
    assert resolved is not None
    pixels, wavelengths = resolved.pixels, resolved.wavelengths  # from the metadata the checks opened
    rt = get_runtime(device or sc.run.device)
    bands = list(checked.analysis_bands) if checked.analysis is not None else []
    fp = cube_footprint(sc, resolved.rows, resolved.cols, wavelengths, resolved.interpolates, bands,
                        on_grid=samples_on_grid(resolved), device_memory=rt.host_memory)
    budget.require(BASELINE_BYTES + total(fp.whole), what=f"a cube of {pixels:,} pixels × {wavelengths} wavelengths",
                   key="surface.cube", source=sc.source,
                   fits="crop the cube or coarsen grid.step_nm")  # a cube's whole part must fit before it is read
    # and one block of rows must fit before it is read
    block_rows = footprint_block_rows(sc, budget, fp, resolved.rows, resolved.cols, wavelengths)
    require_device_launches(rt, sc)
    with errors_in(sc.source):
        parts = checked_parts(checked)
        cube = open_scene_cube(resolved, parts)
        groups = band_groups(sc.sensor, resolved.gsd_m)
    require_free(folder / SIMULATION_NC, 1.02 * cube_disk_bytes(sc, cube.rows, cube.cols, cog=cog) + 2e6)
    warnings = report(checked.caveats)
    t0 = time.perf_counter()
    nc = folder / SIMULATION_NC
    written = [nc, folder / SIMULATION_JSON]
    with claim(folder):
        if on_start:
            on_start(f"{sc.name}: cube", cube.rows * cube.cols)
        with simulation_file(nc) as store:
            streamed = None  # the analysis is fed the rows as they are written: nothing is read back
            if checked.analysis is not None:
                streamed = StreamedAnalysis(rt, sc, list(checked.analysis_bands), checked.analysis, cube.rows,
                                            cube.cols)
            with errors_in(sc.source):
                simulate_cube(rt, parts, cube, progress=progress, store=store if streamed is None else
                              streamed.tee(store), block_rows=block_rows)
            analysis = None
            if streamed is not None:
                analysis = streamed.finish(store, cube, _analysis_step(checked, block_rows))
                written.append(folder / "quicklook.png")
                write_quicklook(store, written[-1], analysis["map"])
            if cog:
                written += write_cogs(store, folder, sc, cube.georef, analysis, groups)
            attrs = {k: (v.item() if hasattr(v, "item") else v) for k, v in store.attrs.items()}
        seconds = time.perf_counter() - t0
        write_json(folder / SIMULATION_JSON, {"scene": sc.name, "attrs": attrs, "pixels": cube.rows * cube.cols,
                                              "block_rows": block_rows, "seconds": seconds, "analysis": analysis,
                                              "warnings": warnings})
    return SimulationRun(sc.name, folder, tuple(written), attrs=attrs, analysis=analysis,
                         pixels=cube.rows * cube.cols, seconds=seconds)


def _analysis_step(checked: Checked, block_rows: int | None) -> int | None:
    """Rows of the analysis's common grid in as many input rows as a block of the simulation (None: all)."""
    sc, bands = checked.scene, list(checked.analysis_bands)
    factor = max(sc.sensor.band(b).gsd_m for b in bands) / (sc.spec.surface.gsd_m or 1.0)
    return None if block_rows is None else max(1, int(block_rows // factor))
