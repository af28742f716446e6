"""A library scene simulated in memory (``s2cl.simulate``): the scene resolved into the chain's parts once
(:func:`s2cl.app.chain_parts.chain_parts`), its library spectra × noisy copies through the chain
(:meth:`s2cl.forward.simulate.Simulator.run_library`). ``s2cl simulate`` streams into a file instead
(:mod:`s2cl.app.simulate`)."""

from __future__ import annotations

from pathlib import Path

from s2cl.app.chain_parts import chain_parts
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError, errors_in
from s2cl.forward.run_attrs import run_attrs
from s2cl.forward.simulate import LibrarySimulation, Progress, Simulator
from s2cl.io.budget import BASELINE_BYTES, Budget, largest_fitting
from s2cl.libraries.library import SpectralLibrary
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene

#: bytes per pixel and band of an in-memory simulation: float32 noisy/calibrated/reflectance and uint16 DN,
#: and the copies :meth:`LibrarySimulation.to_dataset` makes of them
IN_MEMORY_BYTES_PER_PIXEL_BAND = 48


def simulate(scene: Scene | str | Path, *, device: str | None = None, progress: Progress | None = None,
             library: SpectralLibrary | None = None) -> LibrarySimulation:
    """Simulate a library scene (see :class:`Scene`); ``library`` overrides the scene's surface."""
    if not isinstance(scene, Scene):
        scene = Scene.load(scene)
    if scene.spec.surface.cube is not None:
        raise InputError("this scene holds an image cube: use s2cl.app.image_simulation.simulate_image",
                         source=scene.source)
    lib = library if library is not None else scene_library(scene)
    _require_memory(scene, lib)
    rt = get_runtime(device or scene.run.device)
    parts = chain_parts(scene)
    r = scene.run
    with errors_in(scene.source):
        result = Simulator.of(rt, parts).run_library(lib, copies=r.copies, seed=r.seed, frame=r.frame,
                                                     scene_name=scene.name, progress=progress)
    result.attrs.update(run_attrs(parts, rt.name, image=False))
    return result


def _require_memory(scene: Scene, lib: SpectralLibrary) -> None:
    """Refuse an in-memory simulation larger than the memory budget (``s2cl simulate`` streams instead)."""
    copies, nb = scene.run.copies, scene.sensor.size
    per_copy = lib.size * nb * IN_MEMORY_BYTES_PER_PIXEL_BAND
    budget = Budget.of()
    budget.require(BASELINE_BYTES + copies * per_copy, what=f"an in-memory simulation of {lib.size:,} spectra × "
                   f"{copies:,} copies", key="surface.copies", source=scene.source,
                   fits=f"at most {largest_fitting(budget.memory_bytes, BASELINE_BYTES, per_copy):,} copies fit; "
                        "`s2cl simulate` writes any number of copies in bounded memory")
