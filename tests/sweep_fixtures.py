"""Small sweeps for the engine tests (synthetic smooth atmospheric terms; the real ones come from
the 6S LUT and are tested with the atmosphere)."""

from __future__ import annotations

import numpy as np

from s2cl.libraries.registry import load_library
from s2cl.reference.sweep import NumpyEvaluator
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.scene.scene import Scene
from s2cl.sensor.variants import SweepSpace
from s2cl.sweep.engine import SweepJob
from s2cl.sweep.space import sweep_space
from s2cl.sweep.tables import SweepTables, build_tables


class Terms:
    def __init__(self, n: int, scale: float = 1.0):
        x = np.linspace(0, 1, n)
        self.path_radiance = (40.0 - 35.0 * x) * scale
        self.ground_term = (120.0 - 100.0 * x) * scale
        self.spherical_albedo = 0.2 - 0.15 * x


def scene_space(scene: Scene) -> SweepSpace:
    """The scene's [sweep] as the engine reads it (its parts, not the scene)."""
    return sweep_space(scene.spec.sweep, scene.sensor, scene.grid, scene.run.support)


def scene_tables(scene: Scene, space: SweepSpace, lib, truth, assumed, **kwargs) -> SweepTables:
    """:func:`build_tables` with the scene's sensor, grid, run and [effects]."""
    return build_tables(space, lib, truth, assumed, scene.sensor, scene.grid, scene.run, scene.spec.effects, **kwargs)


def scene_analysis(scene: Scene, bands: list[str]) -> AnalysisSettings:
    return AnalysisSettings.from_spec(scene.spec.analysis, bands)


def gvmi_scene(copies: int = 20, b11_max_width: float = 150.0) -> Scene:
    return Scene.from_dict({
        "scene": {"name": "gvmi-test"},
        "surface": {"library": "builtin:leaf-water", "quantity": "reflectance", "copies": copies},
        "effects": {"atmosphere": True, "correct": True, "seed": 4},
        "sweep": {"bands": ["B8", "B11"], "ranges": {
            "B8": {"centre": 842, "width": 115},
            "B11": {"left": 1500, "right": 1750, "min_width": 50, "max_width": b11_max_width}}},
        "analysis": {"kind": "gvmi", "parameter": "ewt", "nir": "B8", "swir": "B11"},
    })


def gvmi_job(chunk: int = 5, copies: int = 20, b11_max_width: float = 150.0) -> SweepJob:
    scene = gvmi_scene(copies, b11_max_width)
    space = scene_space(scene)
    lib = load_library("builtin:leaf-water", scene.grid)
    terms = Terms(scene.grid.size)
    tables = scene_tables(scene, space, lib, terms, terms, target=lib.params["ewt"])
    analysis = scene_analysis(scene, space.bands)
    return SweepJob(tables, analysis, chunk=chunk, scene_name=scene.name)


def numpy_evaluator(job: SweepJob) -> NumpyEvaluator:
    """The float64 numpy twin as the sweep's chunk evaluator (engine tests: exact and fast, no device)."""
    return NumpyEvaluator(job.tables, job.analysis)


#: A small whole-chain sweep scene (Lib1, IGRM, B4 over 3 centres × 2 widths: 6 configurations) for
#: command-line tests; ``{copies}`` noisy copies per spectrum.
SMALL_SWEEP_TOML = """
[scene]
name = "small"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = {copies}
[effects]
atmosphere = true
correct = true
[analysis]
kind = "igrm"
parameter = "cab"
[sweep]
bands = ["B4", "B5", "B6", "B7"]
[sweep.ranges]
B4 = {{ centres = [665, 675, 685], widths = [20, 30] }}
B5 = {{ centre = 705, width = 15 }}
B6 = {{ centre = 740, width = 15 }}
B7 = {{ centre = 783, width = 20 }}
"""
