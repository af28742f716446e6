"""Spectral stability requirement per band (the paper names "spectral stability requirements"
without numbers): how far may a band's centre (or width) drift before an application's error grows by
[study] ``growth`` (10 %) over the nominal?

For each application of [study] ``applications`` (a scene: library, atmosphere, noise, analysis, bands;
:mod:`s2cl.studies.drift`) every band is drifted alone — centre by each of ``shifts_nm``, width by each of
``width_factors`` — while the processing assumes the nominal band: nominal centre (IGRM abscissa), nominal
band-effective correction terms, nominal SAM references, and the regression calibrated once on the nominal
simulation. The noise uses common random numbers (the scene's seed: the same deviates for every drift), so the
curves differ by the drift, not by luck; a noise-free run (quantisation kept) gives the drift's own effect.

The requirement of a band is the drift on each side at which the error first reaches (1 + growth) × the
nominal error, linear between the sampled drifts (:func:`s2cl.studies.common.equal_error`); NaN (printed
"> range") where the sampled drifts never reach it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from s2cl.cl.runtime import get_runtime
from s2cl.io.budget import Budget, gb
from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, equal_error
from s2cl.studies.drift import (
    Application,
    Drifts,
    drift_configs,
    drift_errors,
    drift_tables,
    evaluation_bytes_per_pixel,
    load_application,
)
from s2cl.sweep.kernel import SweepKernel

#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (), ("applications", "shifts_nm")
KINDS = ("shift", "width")


def axes(drifts: Drifts) -> dict[str, np.ndarray]:
    """The sampled drifts with the nominal included: shifts (nm, with 0) and width factors (with 1)."""
    return {"shift": np.array(sorted({0.0, *drifts.shifts})), "width": np.array(sorted({1.0, *drifts.factors}))}


def requirement(x: np.ndarray, error: np.ndarray, nominal: float, growth: float, centre: float) -> dict[str, float]:
    """The drift below and above ``centre`` (0 nm for shifts, 1 for width factors) at which ``error`` (sampled at
    ``x``) first reaches ``(1 + growth) × nominal``: ``minus`` and ``plus``, as distances from ``centre``
    (NaN: not reached in the sampled range, or no finite positive nominal error)."""
    if not (np.isfinite(nominal) and nominal > 0):
        return {"minus": float("nan"), "plus": float("nan")}
    level = (1.0 + growth) * nominal
    return {"minus": equal_error(x - centre, error, level, -1), "plus": equal_error(x - centre, error, level, +1)}


def both_sides(req: dict[str, float]) -> float:
    """The requirement on both sides: the smaller drift, a side not reached counting as unlimited (NaN if
    neither is reached)."""
    return float(np.fmin(req["minus"], req["plus"]))


def evaluate(app: Application, drifts: Drifts, *, noise: bool) -> dict[str, Any]:
    """Errors of ``app`` for every band and drift: ``nominal``, and per kind ``error``, ``recalibrated``,
    ``scored_fraction`` as ``{band: [value per sampled drift]}``."""
    run = app.scene.run
    tables = drift_tables(app, drifts, noise=noise)
    kernel = SweepKernel(tables, app.analysis, get_runtime(run.device), precision=run.precision, lanes=run.lanes)
    ax = axes(drifts)
    configs = {k: drift_configs(app, drifts, k, tuple(ax[k])) for k in KINDS}
    unique, inverse = np.unique(np.concatenate([[0], *(c.ravel() for c in configs.values())]), return_inverse=True)
    errs = drift_errors(app, tables, kernel, unique)
    out: dict[str, Any] = {"nominal": float(errs.error[0]), "pixels": tables.n_pixels}
    start = 1
    for k, c in configs.items():
        idx = inverse[start:start + c.size].reshape(c.shape)
        start += c.size
        for name in ("error", "recalibrated", "scored_fraction"):
            values = getattr(errs, name)[idx]
            out.setdefault(name, {})[k] = {b: values[i].tolist() for i, b in enumerate(app.bands)}
    return out


def _fmt(value: float, limit: float, digits: str = ".2f") -> str:
    """A requirement for the table: ``> limit`` where not reached within the sampled drifts, ``–`` where none
    were sampled."""
    if np.isfinite(value):
        return format(value, digits)
    return f"> {limit:g}" if limit > 0 else "–"


def run(setup: StudySetup) -> StudyResult:
    st = setup.study
    drifts = Drifts(tuple(sorted(set(st.shifts_nm))), tuple(sorted(set(st.width_factors))))
    apps = [load_application(setup.scene, label, ref, st.pixels) for label, ref in st.applications.items()]
    budget = Budget.of()
    for app in apps:
        drifts.check_grid(app, setup.source)
        n = app.library.size * st.pixels
        per_pixel = evaluation_bytes_per_pixel(app.analysis.family.metric, np.dtype(app.scene.run.precision).itemsize)
        budget.require(n * (per_pixel + 8 * len(app.bands)), key="study.pixels", source=setup.source,
                       what=f"application {app.label!r} ({n:,} pixels: {gb(n * per_pixel)} per configuration)")
    ax = axes(drifts)
    max_shift = float(np.abs(ax["shift"]).max())
    max_factor = float(np.abs(ax["width"] - 1).max())
    rows, figures, data_apps = [], [], []
    for app in apps:
        noisy, clean = evaluate(app, drifts, noise=True), evaluate(app, drifts, noise=False)
        req: dict[str, dict[str, dict[str, float]]] = {}
        req_clean: dict[str, dict[str, dict[str, float]]] = {}
        for b, (c, w) in zip(app.bands, app.nominal, strict=True):
            req[b], req_clean[b] = {}, {}
            for k, centre in (("shift", 0.0), ("width", 1.0)):
                req[b][k] = requirement(ax[k], np.array(noisy["error"][k][b]), noisy["nominal"], st.growth, centre)
                req_clean[b][k] = requirement(ax[k], np.array(clean["error"][k][b]), clean["nominal"], st.growth,
                                              centre)
            r, rc, rw = req[b]["shift"], req_clean[b]["shift"], req[b]["width"]
            pct = 100 * max_factor
            rows.append([app.label, b, f"{c:g}/{w:g}", f"{noisy['nominal']:.3g} {app.unit}",
                         _fmt(r["minus"], max_shift), _fmt(r["plus"], max_shift), _fmt(both_sides(r), max_shift),
                         _fmt(100 * rw["minus"], pct, ".1f"), _fmt(100 * rw["plus"], pct, ".1f"),
                         f"{_fmt(rc['minus'], max_shift)} / {_fmt(rc['plus'], max_shift)}"])
        both = {b: both_sides(req[b]["shift"]) for b in app.bands}
        finite = {b: v for b, v in both.items() if np.isfinite(v)}
        note = f"error +{100 * st.growth:g} % over nominal {noisy['nominal']:.3g} {app.unit}; the paper gives no number"
        if finite:
            tightest = min(finite, key=finite.__getitem__)
            figures.append(KeyFigure(f"{app.label}: tightest centre-stability requirement (band {tightest})",
                                     round(finite[tightest], 2), None, "nm", note))
        else:
            figures.append(KeyFigure(f"{app.label}: no band's error reaches +{100 * st.growth:g} % within the shifts",
                                     max_shift, None, "nm", note))
        data_apps.append({
            "label": app.label, "scene": st.applications[app.label], "kind": app.analysis.kind, "metric": app.metric,
            "unit": app.unit, "bands": list(app.bands), "nominal_shapes": [list(s) for s in app.nominal],
            "pixels": noisy["pixels"], "nominal_error": noisy["nominal"], "nominal_error_no_noise": clean["nominal"],
            "error": noisy["error"], "error_no_noise": clean["error"], "recalibrated": noisy["recalibrated"],
            "scored_fraction": noisy["scored_fraction"], "requirement": req, "requirement_no_noise": req_clean,
        })
    data = {"growth": st.growth, "shifts_nm": ax["shift"].tolist(), "width_factors": ax["width"].tolist(),
            "copies": st.pixels, "applications": data_apps}
    return StudyResult(
        title=f"Spectral stability: drift at which the error grows by {100 * st.growth:g} % (nominal processing)",
        columns=["application", "band", "nominal c/w nm", "nominal error", "shift − nm", "shift + nm", "± nm",
                 "width − %", "width + %", "no noise: shift −/+ nm"],
        rows=rows, key_figures=figures, data=data,
        notes=["each band drifted alone (model SRF, eq. 1), processed with the nominal centre, correction terms, "
               "references and calibration; common random numbers (each application's seed), "
               f"{st.pixels} noisy copies per spectrum; '> X': not reached within the sampled drifts."])
