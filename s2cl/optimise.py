"""From a scene to a sweep: tables, analysis, chunking, and the scene's own band set as reference."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from .analysis import AnalysisSettings
from .design import check_design, count_underdetermined
from .errors import InputError
from .library import SpectralLibrary
from .scene import Scene
from .scene_atmosphere import correction_terms, scene_terms
from .simulate import scene_library
from .sweep import SweepJob, auto_chunk, evaluate_chunk
from .sweep_tables import SweepTables, build_tables, sweep_space
from .variants import BandRange, SweepSpace


def _check(scene: Scene) -> None:
    if scene.spec.sweep is None:
        raise InputError("the scene has no [sweep] section: it cannot be optimised (s2cl simulate runs it)",
                         source=scene.source, key="sweep")
    if scene.spec.analysis is None:
        raise InputError("a sweep needs an [analysis] section (igrm, gvmi or sam)", source=scene.source,
                         key="analysis")
    if not (scene.effects.atmosphere and scene.effects.correct):
        raise InputError("a sweep runs the whole chain: set effects.atmosphere = true and effects.correct = true",
                         source=scene.source, key="effects")


def _targets(scene: Scene, lib: SpectralLibrary, analysis: AnalysisSettings
             ) -> tuple[SpectralLibrary, np.ndarray, tuple[str, ...]]:
    """The library (restricted to the SAM classes), the per-spectrum target and the class names."""
    if analysis.kind == "sam":
        wanted = scene.spec.analysis.classes or sorted(set(lib.groups))
        missing = [c for c in wanted if c not in lib.groups]
        if missing:
            raise InputError(f"no spectra of class(es) {', '.join(missing)}; library groups: "
                             f"{', '.join(sorted(set(lib.groups)))}", source=scene.source, key="analysis.classes")
        if len(wanted) < 2:
            raise InputError("SAM needs at least two classes", source=scene.source, key="analysis.classes")
        keep = [i for i, g in enumerate(lib.groups) if g in wanted]
        lib = lib.subset(keep)
        return lib, np.array([wanted.index(g) for g in lib.groups], dtype=np.float64), tuple(wanted)
    param = analysis.parameter
    if param not in lib.params:
        raise InputError(f"library has no parameter {param!r}; it has {', '.join(sorted(lib.params)) or 'none'}",
                         source=scene.source, key="analysis.parameter")
    return lib, np.asarray(lib.params[param], dtype=np.float64), ()


def _tables(scene: Scene, space: SweepSpace, analysis: AnalysisSettings) -> SweepTables:
    lib, target, classes = _targets(scene, scene_library(scene), analysis)
    return build_tables(scene, space, lib, scene_terms(scene), correction_terms(scene), target=target,
                        class_names=classes)


def plan_sweep(scene: Scene, *, backend: str = "opencl", chunk: int | None = None) -> SweepJob:
    """The sweep a scene describes, ready for :func:`s2cl.sweep.run_sweep`."""
    _check(scene)
    space = sweep_space(scene)
    analysis = AnalysisSettings.from_scene(scene, space.bands)
    check_fittable(scene, space, analysis)
    tables = _tables(scene, space, analysis)
    chunk = chunk or scene.spec.sweep.chunk or auto_chunk(tables)
    text = scene.path.read_text(encoding="utf-8") if scene.path else ""
    return SweepJob(tables, analysis, chunk=chunk, backend=backend, precision=scene.spec.output.precision,
                    scene_name=scene.name, scene_text=text, underdetermined=scene.spec.sweep.underdetermined)


def underdetermined_count(space: SweepSpace, analysis: AnalysisSettings) -> int | None:
    """Configurations of ``space`` the analysis cannot fit (:mod:`s2cl.design`), counted without
    enumerating them; None when there are too many distinct centres to count."""
    return count_underdetermined(analysis.kind, space.per_band, nir_slot=analysis.nir_slot,
                                 swir_slot=analysis.swir_slot)


def check_fittable(scene: Scene, space: SweepSpace, analysis: AnalysisSettings) -> None:
    """Refuse, before any work, a sweep in which no configuration can be fitted (one line naming the
    reason, e.g. a fixed design with two IGRM bands on one centre)."""
    bad = underdetermined_count(space, analysis)
    if bad is not None and bad == space.size:
        first = space.shapes(0, 1)[0]
        check_design(analysis.kind, space.bands, first[:, 0], first[:, 1], source=scene.source, key="sweep",
                     nir_slot=analysis.nir_slot, swir_slot=analysis.swir_slot)


def reference_row(scene: Scene, job: SweepJob, device: str | None = None) -> dict[str, Any]:
    """Metrics of the sensor's own band set (e.g. ESA's) with the same library, atmosphere and noise."""
    fixed = SweepSpace(tuple(BandRange.fixed(b, scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm)
                             for b in job.tables.bands)).validate(scene.source)
    tables = _tables(scene, fixed, job.analysis)
    ref = replace(job, tables=tables, chunk=1)
    rows = evaluate_chunk(ref, 0, 1, device)
    return {k: (v[0].item() if isinstance(v, np.ndarray) else v) for k, v in rows.items()}


def count_table(scene: Scene) -> list[dict[str, Any]]:
    """Variants per band (count and extremes) for ``s2cl sweep count``."""
    space = sweep_space(scene)
    rows = []
    for r, v in zip(space.ranges, space.per_band, strict=True):
        rows.append({"band": r.band, "variants": int(v.shape[0]),
                     "centres_nm": f"{v[:, 0].min():g}–{v[:, 0].max():g}",
                     "widths_nm": f"{v[:, 1].min():g}–{v[:, 1].max():g}"})
    return rows
