"""A scene whose surface is a cube file, completed from the file's metadata before anything runs: what a product
says that the scene left open.

- **GSD** (``surface.gsd_m``): absent, it is the pixel size of a product georeferenced in metres (square pixels); a
  product without one (no georeference, or a geographic CRS) needs it in the scene. Given and different from the
  product's pixel size, it is kept (the bands are simulated as if the pixels were that size) and a warning says
  that the outputs' map grids follow the product.
- **Spectral grid** (``[grid]``): a cube that does not cover the grid (EnMAP covers about 420–2450 nm, the default
  grid is 400–2500 nm) gives the grid its coverage, on the same step, when the scene does not set
  ``grid.start_nm`` / ``grid.stop_nm`` and every band's SRF support lies inside it; one warning line says so. A
  band whose support leaves the cube's coverage is refused, naming the band and the file.
- **Quantity**: a product that states what it holds (the L2A products hold surface reflectance) must agree with
  ``surface.quantity``.

The file's metadata is opened once per run: :func:`resolve_cube` (called by the checks,
:func:`s2cl.app.checks.check_simulate`) returns the completed scene and the cube resolved from it
(:class:`s2cl.forward.parts.ResolvedCube`: the reader, its shape, the GSD, the grid, the caveats and whether the
resampling kernel interpolates the file's wavelengths), which the memory rules and the engines take.
"""

from __future__ import annotations

import math
from dataclasses import replace

from s2cl.errors import InputError
from s2cl.forward.grid_interpolation import on_grid
from s2cl.forward.parts import ResolvedCube
from s2cl.grid import SpectralGrid
from s2cl.io.cubes import CubeReader, open_cube
from s2cl.io.inputs import input_file
from s2cl.libraries.fields import fields_shape, is_builtin_cube
from s2cl.scene.caveats import Caveat
from s2cl.scene.scene import Scene
from s2cl.sensor.srf import point_weights

#: relative difference below which two pixel sizes are the same
SAME_SIZE = 1e-6


def scene_reader(scene: Scene) -> CubeReader | None:
    """The scene's cube file opened (metadata only), or None for a generated cube or a library scene."""
    s = scene.spec.surface
    if s.cube is None or is_builtin_cube(s.cube):
        return None
    path = scene.resolve(s.cube)
    if not path.is_dir():  # a folder is a product (EnMAP), checked by its reader
        input_file(path, what="image cube", source=scene.source, key="surface.cube")
    return open_cube(path, s.variable, geometry=s.geometry)


def resolve_cube(scene: Scene) -> tuple[Scene, ResolvedCube | None]:
    """``scene`` with its GSD and spectral grid completed from its cube file's metadata (the module docstring) and
    its cube resolved (:class:`~s2cl.forward.parts.ResolvedCube`: the file opened once, its shape, the caveats that
    say what was taken); ``(scene, None)`` for a library scene. The checks call it once per run and hand the result on
    in :class:`~s2cl.app.checks.Checked` (nothing caches it: a second call opens the file again)."""
    s = scene.spec.surface
    if s.cube is None:
        return scene, None
    if is_builtin_cube(s.cube):
        rows, cols = fields_shape(s.cube, source=scene.source)
        assert s.gsd_m is not None  # a generated cube's GSD is checked with the scene
        return scene, ResolvedCube(None, s.cube, rows, cols, 0, s.gsd_m, scene.grid, False, scene.source,
                                   s.quantity)
    reader = scene_reader(scene)
    assert reader is not None
    source = str(reader.path)
    if reader.quantity is not None and reader.quantity != s.quantity:
        raise InputError(f"{reader.product} holds surface {reader.quantity}; set surface.quantity = "
                         f"'{reader.quantity}' (with effects.atmosphere = true)", source=scene.source,
                         key="surface.quantity")
    caveats: list[Caveat] = []
    gsd = s.gsd_m
    pixel = _pixel_metres(reader)
    if gsd is None:
        if pixel is None:
            why = ("it has no georeference" if reader.georef is None else
                   f"its pixels are {reader.georef.pixel_size[0]:.6g} × {reader.georef.pixel_size[1]:.6g} "
                   f"{reader.georef.units()}s")
            raise InputError(f"an image cube needs surface.gsd_m (its ground sampling distance in m): {reader.product}"
                             f" {reader.path.name} does not give it in metres ({why})", source=scene.source,
                             key="surface.gsd_m")
        gsd = pixel
    elif pixel is not None and abs(pixel - gsd) > SAME_SIZE * gsd:
        caveats.append(Caveat("surface.gsd_m", f"{gsd:g} m, but the pixels of {reader.path.name} are {pixel:g} m: the "
                              f"bands are simulated as if they were {gsd:g} m; the outputs' map grids follow the "
                              f"product (a band pixel of k input pixels is k × {pixel:g} m on the map)"))
    grid, note = _coverage_grid(scene, reader, source)
    if note:
        caveats.append(note)
    if gsd != s.gsd_m or grid is not scene.grid:
        spec = scene.spec.model_copy(update={"surface": s.model_copy(update={"gsd_m": gsd})})
        scene = replace(scene, spec=spec, grid=grid)
    cube = ResolvedCube(reader, None, reader.rows, reader.cols, reader.bands_read, gsd, grid,
                        not on_grid(reader.wavelengths_nm, grid), str(scene.resolve(s.cube)), s.quantity,
                        tuple(caveats))
    return scene, cube


def resolve_product_scene(scene: Scene) -> tuple[Scene, tuple[Caveat, ...]]:
    """``scene`` completed from its cube file's metadata (:func:`resolve_cube`), and the warnings that say what was
    taken; ``scene`` itself when there is nothing to complete."""
    resolved, cube = resolve_cube(scene)
    return resolved, () if cube is None else cube.caveats


def _pixel_metres(reader: CubeReader) -> float | None:
    """The product's square pixel size in metres (None without a georeference in metres, or non-square pixels)."""
    g = reader.georef
    if g is None or g.units() != "metre":
        return None
    px, py = g.pixel_size
    return px if abs(px - py) <= SAME_SIZE * px else None


def _coverage_grid(scene: Scene, reader: CubeReader, source: str) -> tuple[SpectralGrid, Caveat | None]:
    """The scene's grid, or (the cube does not cover it and the scene does not set its ends) the grid on the same
    step inside the cube's coverage, with the warning that says so; a band whose SRF support leaves the coverage is
    an :class:`InputError` naming it."""
    grid, w = scene.grid, reader.wavelengths_nm
    lo, hi = float(w[0]), float(w[-1])
    if lo <= grid.start_nm + 1e-9 and hi >= grid.stop_nm - 1e-9:
        return grid, None
    if {"start_nm", "stop_nm"} & scene.spec.grid.model_fields_set:
        return grid, None  # the scene's own grid: the reader refuses it with the key to change
    step = grid.step_nm  # the grid's own samples inside the coverage: never wider than the grid it replaces
    start = grid.start_nm + max(0, math.ceil((lo - grid.start_nm) / step - 1e-9)) * step
    stop = min(grid.stop_nm, grid.start_nm + math.floor((hi - grid.start_nm) / step + 1e-9) * step)
    if stop - start < step:
        raise InputError(f"covers {lo:g}–{hi:g} nm: too narrow for any band", source=source, key="wavelength")
    new = SpectralGrid(round(start, 9), round(stop, 9), step)
    for band in scene.sensor.bands:
        try:
            if scene.effects.resample:
                band.weights(new, scene.spec.sensor.support, source)
            else:
                point_weights(new, band.centre_nm, band.name, source)
        except InputError:
            reach = scene.spec.sensor.support * band.fwhm_nm
            raise InputError(f"{reader.product} covers {lo:g}–{hi:g} nm; band {band.name}'s SRF support "
                             f"{band.centre_nm - reach:g}–{band.centre_nm + reach:g} nm leaves it", source=source,
                             key="wavelength") from None
    return new, Caveat("grid", f"the cube covers {lo:g}–{hi:g} nm, not the grid {grid.start_nm:g}–{grid.stop_nm:g} nm: "
                       f"the grid is taken from its coverage, {new.describe()} (every band's SRF support lies inside)")
