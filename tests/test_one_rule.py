"""One design, one verdict: ``s2cl simulate`` and a one-configuration sweep of the same bands give every
pixel the same status and the same index.

Both paths run the same stage functions (kernels/common/stages.mako, common/igrm_lm.mako) on the same
noise (Philox keyed by pixel and the band's index in the sensor); they differ only in how the noise-free
band radiance is summed (the resampling kernel per wavelength, the sweep tables in numpy), so in float64
values agree to rounding and statuses exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.app.analysis import pixel_results
from s2cl.app.library_simulation import simulate
from s2cl.app.plan import plan_sweep
from s2cl.errors import InputError
from s2cl.retrieve.design import design_problem
from s2cl.scene.scene import Scene
from s2cl.status import Status
from s2cl.sweep.kernel import SweepKernel

ESA = {"B4": (665, 30), "B5": (705, 15), "B6": (740, 15), "B7": (783, 20), "B8a": (865, 20), "B11": (1610, 90),
       "B12": (2190, 180)}

CASES = {
    "igrm": ({"library": "builtin:lib1", "copies": 12}, ["B4", "B5", "B6", "B7"], {"kind": "igrm", "parameter": "cab"}),
    "gvmi": ({"library": "builtin:leaf-water", "copies": 8}, ["B8a", "B11"],
             {"kind": "gvmi", "parameter": "ewt", "nir": "B8a", "swir": "B11"}),
    "sam": ({"library": "builtin:minerals-swir", "copies": 10}, ["B11", "B12"],
            {"kind": "sam", "angle_threshold_deg": 4.0}),
    "formula": ({"library": "builtin:lib1", "copies": 12}, ["B4", "B5", "B6", "B7"],
                {"kind": "formula", "expression": "705 + 35 * ((B4 + B7) / 2 - B5) / (B6 - B5)", "parameter": "cab"}),
}
#: how close the two paths' values are: IGRM λp (nm), GVMI, SAM class, S2REP (nm; measured identical, but its B6 - B5
#: denominator would amplify any rounding difference of the two paths' band sums)
TOL = {"igrm": 1e-6, "gvmi": 1e-12, "sam": 0.0, "formula": 1e-9}
GRID = {"sam": {"start_nm": 1500, "stop_nm": 2500}}


def _scene(kind: str, bands: dict[str, tuple[float, float]] | None = None, **sensor: str) -> Scene:
    surface, names, analysis = CASES[kind]
    bands = bands or {b: ESA[b] for b in names}
    return Scene.from_dict({
        "scene": {"name": f"one-rule-{kind}"},
        "surface": {**surface, "quantity": "reflectance"},
        "sensor": {"bands": list(bands), **sensor},
        "effects": {"atmosphere": True, "correct": True, "seed": 5},
        "sweep": {"bands": list(bands), "ranges": {b: {"centre": c, "width": w} for b, (c, w) in bands.items()}},
        "analysis": analysis,
        "compute": {"precision": "float64"},
        **({"grid": GRID[kind]} if kind in GRID else {}),
    })


@pytest.mark.parametrize("kind", list(CASES))
def test_simulate_and_sweep_give_each_pixel_one_verdict(rt, kind: str) -> None:
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    scene = _scene(kind)
    swept, direct = _one_verdict(rt, kind, scene, scene)
    if kind == "igrm":
        np.testing.assert_array_equal(swept.bounds[0], direct.bounds)
        assert np.max(np.abs(swept.condition[0].astype(int) - direct.condition.astype(int))) <= 1
        assert np.mean(direct.status == Status.OK) > 0.9
    if kind == "sam":
        assert {Status.OK, Status.UNCLASSIFIED} <= set(np.unique(direct.status).tolist())  # both verdicts occur


#: bands moved off their reference shape: narrower, wider and shifted (the noise rescales with the width)
MOVED = {"igrm": {"B5": (712.0, 10.0), "B6": (748.0, 25.0)}, "gvmi": {"B11": (1610.0, 50.0)},
         "sam": {"B12": (2200.0, 60.0)}, "formula": {"B5": (712.0, 10.0), "B6": (748.0, 25.0)}}


@pytest.mark.parametrize("kind", list(CASES))
def test_moved_bands_give_each_pixel_one_verdict(rt, kind: str) -> None:
    """A sweep's one configuration that moves bands off the sensor's shapes, against ``simulate`` of a sensor
    whose bands are those shapes (``Band.with_shape``): same noise, so the same value and status per pixel.
    The sweep's tables (radiance and noise σ per variant) are thus checked against the direct path at widths
    other than the reference: σ of the base band instead of the variant's lowers it 25 % at a 50 nm B11."""
    if not rt.has_fp64:
        pytest.skip("device has no cl_khr_fp64")
    from dataclasses import replace

    from s2cl.sensor.sensor import Sensor

    bands = {b: MOVED[kind].get(b, ESA[b]) for b in CASES[kind][1]}
    swept_scene = _scene(kind, bands)  # the sensor's own (ESA) bands; the sweep moves them
    esa = swept_scene.sensor
    moved = Sensor(esa.name, tuple(b.with_shape(*bands[b.name]) for b in esa.bands), bits=esa.bits, source=esa.source)
    assert any(b.noise_coefficients() != e.noise_coefficients() for b, e in zip(moved.bands, esa.bands, strict=True))
    _one_verdict(rt, kind, replace(swept_scene, sensor=moved), swept_scene)


def _one_verdict(rt, kind: str, direct_scene: Scene, swept_scene: Scene):
    """``simulate``'s analysis of ``direct_scene`` and the one-configuration sweep of ``swept_scene`` in float64:
    the same status per pixel and the same value within :data:`TOL`; both results, for more checks."""
    direct = pixel_results(rt, direct_scene, simulate(direct_scene))
    job = plan_sweep(swept_scene)
    assert job.n_configs == 1
    swept = SweepKernel(job.tables, job.analysis, rt, precision="float64")(0, 1)
    np.testing.assert_array_equal(swept.status[0], direct.status)
    np.testing.assert_allclose(swept.index[0], direct.index, rtol=0, atol=TOL[kind])
    return swept, direct


def test_coincident_igrm_centres_get_the_same_one_line_verdict_everywhere(rt, tmp_path) -> None:
    """A sensor whose B5 and B6 share a centre (a user sensor table): `simulate`'s analysis and the
    sweep of that fixed design refuse it before any work, with the same explained message; the
    direct fitter refuses the wavelengths too."""
    import importlib.resources

    bands = {"B4": (665, 30), "B5": (730, 20), "B6": (730, 30), "B7": (783, 20)}
    table = (importlib.resources.files("s2cl") / "data" / "sentinel2_mrd_table1.csv").read_text()
    sensor = tmp_path / "sensor.csv"
    sensor.write_text(table.replace("\nB5,705,15,", "\nB5,730,20,").replace("\nB6,740,15,", "\nB6,730,30,"))
    scene = _scene("igrm", bands, file=str(sensor))
    problem = design_problem("igrm", list(bands), [c for c, _ in bands.values()], [w for _, w in bands.values()])
    assert problem and "B5 and B6 at 730 nm" in problem and "3 distinct centres" in problem
    from s2cl.app.analysis import analysis_design

    with pytest.raises(InputError, match="underdetermined") as direct:
        analysis_design(scene)
    with pytest.raises(InputError, match="underdetermined") as swept:
        plan_sweep(scene)
    assert problem in str(direct.value) and problem in str(swept.value)
    assert "\n" not in str(direct.value)
    from s2cl.retrieve.igrm import IgrmFitter

    with pytest.raises(InputError, match="underdetermined"):
        IgrmFitter(rt, 4).fit(np.zeros((4, 3)), np.array([665.0, 730.0, 730.0, 783.0]))
