"""A library scene simulated in memory (``s2cl.simulate``): the scene resolved into the chain's parts once
(:func:`s2cl.app.chain_parts.chain_parts`), its library spectra × noisy copies through the chain
(:meth:`s2cl.forward.simulate.Simulator.run_library`). ``s2cl simulate`` streams into a file instead
(:mod:`s2cl.app.simulate`)."""

from __future__ import annotations

from pathlib import Path

from s2cl.app.chain_parts import chain_parts
from s2cl.app.simulate_footprint import in_memory_footprint
from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError, errors_in
from s2cl.forward.run_attrs import run_attrs
from s2cl.forward.simulate import LibrarySimulation, Progress, Simulator
from s2cl.io.budget import Budget
from s2cl.libraries.library import SpectralLibrary
from s2cl.scene.library import scene_library
from s2cl.scene.scene import Scene


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
    """Refuse an in-memory simulation larger than the memory budget (``s2cl simulate`` streams instead): what it
    allocates, and its :meth:`~s2cl.forward.simulate.LibrarySimulation.to_dataset`
    (:func:`s2cl.app.simulate_footprint.in_memory_footprint`)."""
    budget = Budget.of()

    def need(copies: int) -> float:
        return in_memory_footprint(scene, lib.size, copies=copies).peak

    if need(scene.run.copies) <= budget.memory_bytes:
        return
    lo, hi = 0, scene.run.copies  # the most copies that fit, by bisection
    while lo < hi:
        mid = (lo + hi + 1) // 2
        lo, hi = (mid, hi) if need(mid) <= budget.memory_bytes else (lo, mid - 1)
    budget.require(need(scene.run.copies), what=f"an in-memory simulation of {lib.size:,} spectra × "
                   f"{scene.run.copies:,} copies", key="surface.copies", source=scene.source,
                   fits=f"at most {lo:,} copies fit; `s2cl simulate` writes any number of copies in bounded memory")
