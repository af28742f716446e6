"""One writer of ``simulation.nc`` (:mod:`s2cl.io.simulation_file`) and one builder of its run attributes
(:func:`s2cl.forward.run_attrs.run_attrs`), for a library scene and an image cube alike: the attribute set and values
written out by hand for a small scene of each kind; a mark put into the builder's module shows in both files (and in
the in-memory simulation), so no path builds them on its own."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

import s2cl
from s2cl.app.library_simulation import simulate
from s2cl.app.simulate_scene import simulate_scene
from s2cl.cl.runtime import get_runtime
from s2cl.io.simulation_file import simulation_file
from s2cl.scene.scene import Scene

LIBRARY = """[scene]
name = "lib-attrs"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 2
select = { cab = [30, 32] }
[effects]
atmosphere = true
correct = true
psf = true
seed = 7
[compute]
precision = "float64"
"""
CUBE = """[scene]
name = "cube-attrs"
[surface]
cube = "builtin:fields:12x12"
gsd_m = 10.0
quantity = "reflectance"
[effects]
atmosphere = true
correct = true
psf = true
seed = 7
[compute]
precision = "float64"
"""
#: the stages on, as each kind of scene runs them: the library scene does not run the PSF (an image-only stage)
LIBRARY_EFFECTS = "atmosphere, resample, noise, quantise, calibrate, correct"
CUBE_EFFECTS = "atmosphere, resample, psf, noise, quantise, calibrate, correct"


def _global_attrs(path) -> dict:
    with h5py.File(path) as f:
        return {k: (v.decode() if isinstance(v, bytes) else v.item() if getattr(v, "size", 0) == 1 else v)
                for k, v in f.attrs.items() if k != "_NCProperties"}


def _run(tmp_path, text: str, name: str):
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    simulate_scene(str(path), tmp_path / name)
    return path, _global_attrs(tmp_path / name / "simulation.nc")


def test_the_run_attributes_of_a_library_and_a_cube_file_by_hand(tmp_path) -> None:
    device = get_runtime(None).name
    lib_path, lib = _run(tmp_path, LIBRARY, "lib")
    cube_path, cube = _run(tmp_path, CUBE, "cube")
    # the library file: the run's attributes as text (as its in-memory Dataset has them), then the library's own
    assert lib == {"Conventions": "CF-1.10", "scene": "lib-attrs", "scene_file": str(lib_path),
                   "s2cl_version": s2cl.__version__, "device": device, "precision": "float64",
                   "effects": LIBRARY_EFFECTS, "seed": "7", "layout": "rows",
                   "sensor": "Sentinel-2 MSI (MRD, Segl et al. 2012 Table 1)", "bits": 12, "copies": 2,
                   "library_source": lib["library_source"], "quantity": "reflectance"}
    assert lib["library_source"].startswith("lib1: PROSAIL")
    # the cube file: the same run attributes (no layout: an image has its own), then the image's own
    run = {"Conventions": "CF-1.10", "scene": "cube-attrs", "scene_file": str(cube_path),
           "s2cl_version": s2cl.__version__, "device": device, "precision": "float64", "effects": CUBE_EFFECTS,
           "seed": 7}
    assert {k: cube[k] for k in run} == run
    assert set(cube) - set(run) == {"input_gsd_m", "psf", "nodata_input_pixels", "instrument", "georeference"}
    assert (cube["input_gsd_m"], cube["psf"], cube["nodata_input_pixels"]) == (10.0, "gaussian", 0)


def test_every_path_takes_its_run_attributes_from_the_one_builder(tmp_path, monkeypatch) -> None:
    monkeypatch.setattr("s2cl.forward.run_attrs.__version__", "builder-mark")
    assert _run(tmp_path, LIBRARY, "lib")[1]["s2cl_version"] == "builder-mark"
    assert _run(tmp_path, CUBE, "cube")[1]["s2cl_version"] == "builder-mark"
    (tmp_path / "mem.toml").write_text(LIBRARY)
    assert simulate(Scene.load(str(tmp_path / "mem.toml"))).attrs["s2cl_version"] == "builder-mark"


def test_the_writer_leaves_no_file_behind_an_error(tmp_path) -> None:
    target = tmp_path / "simulation.nc"
    with pytest.raises(ValueError, match="stop"), simulation_file(target) as store:
        store.dimension("x", np.arange(3), {})
        store.attrs["scene"] = "half"
        raise ValueError("stop")
    assert list(tmp_path.iterdir()) == []
