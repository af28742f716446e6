"""Drifted bands processed as nominal ones, for ``s2cl study stability``.

An *application* is a scene with an [analysis] and a [sweep] section (e.g. ``table3-lib1-b4567``): its
library, atmosphere, correction, noise seed and analysis, and the bands its [sweep] names, each at the
sensor's own (nominal) centre and width. A *drift* moves one band's model SRF (paper eq. 1): its centre by
δ nm, or its width by a factor. The drifted instrument's data are processed as if the band had not moved.

The composition is the sweep engine's (:mod:`s2cl.sweep.tables`): per band variant the tables hold the
band radiance, its noise σ and the band-effective correction terms. :func:`drift_tables` keeps each drifted
variant's radiance and σ (what the drifted instrument records, with the noise of its own width) and replaces
everything the processing assumes by the nominal variant's entry: the band centre (the IGRM abscissa), the
width, the correction terms (Lp, G, S) and the SAM class references. Quantisation limits are the band's
(Lmin, Lmax, bits) as always. Noise deviates are common random numbers: pixel p of band B gets the same
deviate in every drift (the sensor-noise stream keyed by the scene's seed, pixel and band).

Errors (:func:`drift_errors`): a regression (IGRM λp → Cab, GVMI → EWT) is calibrated once, a second-order
polynomial fitted on the nominal configuration's pixels; every drift is scored with that fixed polynomial
(RMS against the library's parameter, over the pixels whose status enters the regression). SAM: mean
omission error (%) against the nominal references. Units: the parameter's (µg/cm² for Cab, µm for EWT), %.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from s2cl.app.checks import Checked, check_sweep
from s2cl.cl.kernel_args import buffers
from s2cl.errors import InputError, errors_in, key_token
from s2cl.forward.stages import stage
from s2cl.io.inputs import input_file
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.analysis import AnalysisSettings, analysis_targets
from s2cl.retrieve.metric import Metric
from s2cl.retrieve.metrics import ROW_BLOCK, block_work_bytes, regression_metrics
from s2cl.retrieve.quantify import fit_polynomial
from s2cl.scene.scene import Scene, builtin_scenes
from s2cl.sensor.variants import BandList, SweepSpace
from s2cl.sweep.kernel import OUTPUTS
from s2cl.sweep.raw import ChunkEvaluator
from s2cl.sweep.tables import SweepTables, build_tables

#: bytes of the host's float64 work values and of a bool mask value
F64, BOOL = np.dtype(np.float64).itemsize, np.dtype(np.bool_).itemsize


def evaluation_bytes_per_pixel(metric: Metric, real_bytes: int) -> float:
    """Host bytes per pixel of one configuration's evaluation (:func:`drift_errors`): the sweep kernel's outputs as
    fetched (their declared types, :data:`s2cl.sweep.kernel.OUTPUTS`), the metrics' work for its one row
    (:func:`s2cl.retrieve.metrics.block_work_bytes`), and the nominal fit's scoring: the regression masks (bool), the
    used index taken and, in float64, its prediction and residual."""
    fetched = sum(b.per_unit for b in buffers(OUTPUTS, {"pitch": 1}, real_bytes, "configs"))
    metrics = block_work_bytes(1, classifies=metric.classifies) / ROW_BLOCK
    scoring = 3 * BOOL + real_bytes + 2 * F64
    return fetched + metrics + (0 if metric.classifies else scoring)


@dataclass(frozen=True)
class Application:
    """One application of the stability study: a checked scene (copies replaced) and what it analyses."""

    label: str
    scene: Scene
    analysis: AnalysisSettings
    bands: tuple[str, ...]
    #: nominal (centre, width) of each band, nm: the sensor's own shapes
    nominal: tuple[tuple[float, float], ...]
    library: SpectralLibrary
    #: the scene resolved by the checks (its atmosphere terms and sensor build the drift tables)
    checked: Checked

    @property
    def metric(self) -> str:
        """What the error is: RMS of the regressed parameter, or SAM's mean omission error."""
        return self.analysis.family.score_label(self.analysis)

    @property
    def unit(self) -> str:
        return self.analysis.family.metric.unit(self.analysis.parameter)


def load_application(study: Scene, label: str, ref: str, copies: int) -> Application:
    """The scene ``ref`` of [study] ``applications.LABEL`` (a built-in name, or a .toml file relative to the
    study scene), checked as a sweep would check it (:func:`s2cl.app.checks.check_sweep`), with ``copies``
    noisy copies per spectrum."""
    key = f"study.applications.{key_token(label)}"
    if ref.endswith(".toml") or "/" in ref or "\\" in ref:
        path = input_file(study.resolve(ref), what="scene file", source=study.source, key=key)
    elif ref in builtin_scenes():
        path = builtin_scenes()[ref]
    else:
        raise InputError(f"no built-in scene {ref!r} (give a .toml file for a scene of your own); built-in: "
                         f"{', '.join(builtin_scenes())}", source=study.source, key=key)
    scene = Scene.load(path)
    if scene.spec.study is not None:
        raise InputError(f"{ref!r} is a study scene; an application is a scene with [analysis] and [sweep]",
                         source=study.source, key=key)
    scene = replace(scene, run=replace(scene.run, copies=copies))
    checked = check_sweep(scene)
    assert checked.space is not None and checked.analysis is not None
    bands = tuple(checked.space.bands)
    nominal = tuple((scene.sensor.band(b).centre_nm, scene.sensor.band(b).fwhm_nm) for b in bands)
    assert checked.library is not None   # check_sweep refuses a cube
    return Application(label, scene, checked.analysis, bands, nominal, checked.library, checked)


@dataclass(frozen=True)
class Drifts:
    """The drifts of every band: shifts (nm) and width factors, each with its variant per band slot."""

    shifts: tuple[float, ...]
    factors: tuple[float, ...]

    def shapes(self, nominal: tuple[float, float]) -> list[tuple[float, float]]:
        """The distinct variants of a band: the nominal first, then shifted, then widened copies."""
        c, w = nominal
        out = [(c, w)]
        out += [(c + d, w) for d in self.shifts if d != 0]
        out += [(c, w * f) for f in self.factors if f != 1]
        return list(dict.fromkeys(out))

    def variant(self, nominal: tuple[float, float], kind: str, value: float) -> int:
        """Variant index of drift ``kind`` (``"shift"`` or ``"width"``) by ``value`` of a band."""
        c, w = nominal
        shape = (c + value, w) if kind == "shift" else (c, w * value)
        return self.shapes(nominal).index(shape)

    def check_grid(self, app: Application, source: str) -> None:
        """Every drifted SRF (centre ± support × width) inside the application's grid."""
        grid, support = app.scene.grid, app.scene.run.support
        for band, nominal in zip(app.bands, app.nominal, strict=True):
            for c, w in self.shapes(nominal):
                if not grid.covers(c - support * w, c + support * w):
                    key = "study.shifts_nm" if w == nominal[1] else "study.width_factors"
                    raise InputError(f"band {band} of application {app.label!r} moved to {c:g}/{w:g} nm reaches "
                                     f"{c - support * w:g}–{c + support * w:g} nm, outside its grid "
                                     f"{grid.describe()}", source=source, key=key)


def drift_space(app: Application, drifts: Drifts) -> SweepSpace:
    """Every band of ``app`` with its drifted variants (:class:`BandList`, the nominal first)."""
    return SweepSpace(tuple(BandList(b, tuple(drifts.shapes(n))) for b, n in zip(app.bands, app.nominal,
                                                                                    strict=True))).validate()


def drift_tables(app: Application, drifts: Drifts, *, noise: bool = True) -> SweepTables:
    """Sweep tables of ``app`` in which each drifted variant keeps its radiance and σ and takes the nominal
    variant's centre, width, correction terms and SAM references (what the processing assumes). Without
    ``noise``: one copy per spectrum, no noise (quantisation stays)."""
    scene, checked = app.scene, app.checked
    run = scene.run if noise else replace(scene.run, copies=1)
    assert checked.truth is not None and checked.assumed is not None and checked.sensor is not None
    with errors_in(scene.source):
        lib, target, classes = analysis_targets(app.library, app.analysis, scene.spec.analysis.classes)
        t = build_tables(drift_space(app, drifts), lib, checked.truth, checked.assumed, checked.sensor, scene.grid, run,
                         scene.spec.effects, target=target, class_names=classes)

    def nominal(arrays: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        return tuple(np.repeat(a[:1], len(a), axis=0) for a in arrays)

    # the processing's per-variant values (the correction's terms) are the nominal's; per-pixel ones (σ) the variant's
    values = {**t.values, **{v.name: nominal(t.values[v.name]) for v in t.inputs() if v.varies == "variant"}}
    stages = t.stages if noise else tuple(n for n in t.stages if not stage(n).deviates)
    return replace(t, centre=nominal(t.centre), width=nominal(t.width), values=values,
                   references=nominal(t.references), stages=stages)


def drift_configs(app: Application, drifts: Drifts, kind: str, values: tuple[float, ...]) -> np.ndarray:
    """Configuration numbers ``(n_bands, n_values)`` of each band drifted by each value, the others nominal."""
    space = drift_space(app, drifts)
    out = np.empty((len(app.bands), len(values)), dtype=np.int64)
    for k, nominal in enumerate(app.nominal):
        for j, v in enumerate(values):
            idx = [0] * len(app.bands)
            idx[k] = drifts.variant(nominal, kind, v)
            out[k, j] = space.index_of(idx)
    return out


@dataclass
class DriftErrors:
    """Errors of configurations, in the order asked: with the nominal calibration (``error``), with a
    calibration refitted on the drifted data itself (``recalibrated``: the sweep's own metric), and the
    fraction of pixels scored."""

    error: np.ndarray
    recalibrated: np.ndarray
    scored_fraction: np.ndarray


def drift_errors(app: Application, tables: SweepTables, evaluate: ChunkEvaluator, configs: np.ndarray) -> DriftErrors:
    """Score configurations ``configs`` (the first must be 0, the nominal) of ``tables`` one at a time.

    :param evaluate: ``evaluate(start, stop) -> RawChunk`` (:class:`s2cl.sweep.kernel.SweepKernel`).
    """
    configs = np.asarray(configs, dtype=np.int64).ravel()
    if configs.size == 0 or configs[0] != 0:
        raise ValueError("the first configuration must be the nominal one (0)")
    a, target = app.analysis, tables.target
    error, recal, scored = (np.empty(configs.size) for _ in range(3))
    fit = None
    for i, c in enumerate(configs):
        raw = evaluate(int(c), int(c) + 1)
        if a.family.metric.classifies:  # no fit to hold fixed: the error is the metric's score
            m = a.family.metric.metrics(raw.index, raw.status, raw.bounds, target, regress=a.regress,
                                        n_classes=len(tables.class_names))
            error[i] = recal[i] = m[a.family.metric.score_column][0]
            scored[i] = 1.0 - m["unclassified_fraction"][0]
            continue
        x = raw.index[0]
        use = np.isin(raw.status[0], a.regress) & np.isfinite(x)
        if fit is None:
            fit = fit_polynomial(x, target, degree=2, mask=use)
        residual = fit.predict(x[use]) - target[use]
        error[i] = float(np.sqrt(np.mean(residual**2))) if residual.size else np.nan
        recal[i] = regression_metrics(raw.index, raw.status, raw.bounds, target, regress=a.regress)["rms"][0]
        scored[i] = float(use.mean())
    return DriftErrors(error, recal, scored)
