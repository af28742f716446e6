"""A scene's image cube through the forward chain, from the scene: the scene resolved once (its cube file's metadata
opened once, :func:`s2cl.app.product_scene.resolve_cube`; its chain's parts, :func:`s2cl.app.chain_parts.chain_parts`)
and handed to the engines of :mod:`s2cl.forward.cube`, which take parts. Errors name the scene's file (the engines
name the key). ``s2cl simulate`` (:mod:`s2cl.app.simulate_scene`) takes the same steps from its checked scene."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from s2cl.app.chain_parts import chain_parts
from s2cl.app.product_scene import resolve_cube
from s2cl.cl.runtime import Runtime
from s2cl.errors import InputError, errors_in
from s2cl.forward.cube import SceneCube, cube_in_memory, open_scene_cube, simulate_cube
from s2cl.forward.parts import ChainParts, ResolvedCube
from s2cl.forward.simulate import Progress
from s2cl.io.image_store import ImageStore
from s2cl.scene.scene import Scene

if TYPE_CHECKING:
    import xarray as xr  # the in-memory result's type; xarray is imported where one is built


def scene_cube(scene: Scene, cube: np.ndarray | None = None, wavelengths_nm: np.ndarray | None = None) -> SceneCube:
    """The scene's ``surface.cube`` (a file or a generated cube), or ``cube`` given in memory (NaN marks no data;
    ``wavelengths_nm`` None: the scene's grid), made ready for the chain with every check done before any output
    (:func:`s2cl.forward.cube.open_scene_cube`, :func:`~s2cl.forward.cube.cube_in_memory`)."""
    return _prepared(*_resolved(scene, cube), cube, wavelengths_nm)


def simulate_image(rt: Runtime, scene: Scene, cube: np.ndarray | SceneCube | None = None,
                   wavelengths_nm: np.ndarray | None = None, *, progress: Progress | None = None,
                   store: ImageStore | None = None, block_rows: int | None = None) -> xr.Dataset | None:
    """Simulate the scene's image cube (its ``surface.cube``, ``cube`` given in memory, or a cube already made ready
    by :func:`scene_cube`) on ``rt`` (:func:`s2cl.forward.cube.simulate_cube`): a Dataset, or (``store`` given)
    nothing, its variables written into ``store``; ``block_rows``: input rows simulated at a time."""
    resolved, file, parts = _resolved(scene, cube)
    prepared = cube if isinstance(cube, SceneCube) else _prepared(resolved, file, parts, cube, wavelengths_nm)
    with errors_in(resolved.source):
        return simulate_cube(rt, parts, prepared, progress=progress, store=store, block_rows=block_rows)


def _resolved(scene: Scene, cube: np.ndarray | SceneCube | None) -> tuple[Scene, ResolvedCube | None, ChainParts]:
    """The scene completed from its cube's metadata (unless the cube is given in memory), its cube so resolved
    (:func:`s2cl.app.product_scene.resolve_cube`: opened once) and its chain's parts."""
    resolved: ResolvedCube | None = None
    if not isinstance(cube, np.ndarray):
        scene, resolved = resolve_cube(scene)
    with errors_in(scene.source):
        return scene, resolved, chain_parts(scene)


def _prepared(scene: Scene, resolved: ResolvedCube | None, parts: ChainParts, cube: np.ndarray | None,
              wavelengths_nm: np.ndarray | None) -> SceneCube:
    with errors_in(scene.source):
        if cube is not None:
            return cube_in_memory(cube, wavelengths_nm, parts.grid, parts.sensor, scene.spec.surface.gsd_m)
        if resolved is None:
            raise InputError("the scene has no surface.cube", key="surface.cube")
        return open_scene_cube(resolved, parts)
