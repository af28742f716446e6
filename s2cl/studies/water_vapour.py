"""B9 water vapour (paper Sec. 3.2): two-channel APDA retrieval, B8a reference and B9 absorption.

Truth: each target spectrum of [study] ``targets`` under the [atmosphere] state with each water
column of [study] ``water_vapour`` (g/cm²) → band radiances → sensor noise (the SNR-table noise model
with the sense kernel's Philox deviates, :func:`s2cl.studies.common.noisy`; one noise
stream per [sweep] band, shared by its variants).

Retrieval (APDA, Schläpfer et al. 1998, two channels): for every node ``w`` of a fine water-vapour
axis the band-effective LUT terms of the assumed state give the path-radiance-corrected ratio

    R(w) = (L9 − Lp9(w)) / (L8a − Lp8a(w))

and its model for a target as bright in B9 as in B8a, ``R_m(w) = G9(w)/G8a(w) · (1 − S8a·ρ)/(1 − S9·ρ)``
with ρ the B8a reflectance corrected at ``w``. R_m falls monotonically with ``w``; the retrieved
column is the crossing ``R(w) = R_m(w)`` (linear in √w between nodes). Error: relative RMS of
retrieved vs true WV over pixels and true columns, per target class.

The band variants are the [sweep] section (B9 centre × width, B8a shifts). Winter scenes (MLW truth)
are retrieved with the winter and with the summer LUT terms for the nominal bands.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from s2cl.libraries.library import SpectralLibrary
from s2cl.sensor.srf import BandWeights
from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, apply, band_terms, crossing, inverse, noisy, rel_rms

PAPER_RMS_PCT = (5.0, 10.0)   # "the 5–10 % accuracy of the 865-/945-nm water vapor retrievals"
# "Relative RMS errors ... increase by 6 % if winter scenes are processed with summer LUTs"
PAPER_WINTER_INCREASE_PCT = 6.0
#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = ("B9", "B8a"), ("water_vapour", "targets")
SUMMER, WINTER = "midlatitude_summer", "midlatitude_winter"


def wv_axis(setup: StudySetup, n: int = 48) -> np.ndarray:
    """Retrieval nodes (g/cm²), uniform in √w inside the LUT's range at the scene's zenith."""
    lo, hi = setup.lut.water_vapour_range(setup.truth().solar_zenith)
    return np.linspace(np.sqrt(max(lo, 0.2) * 1.001), np.sqrt(min(hi, 5.0) * 0.999), n) ** 2


def band_weights(setup: StudySetup, variants: dict[str, np.ndarray]) -> dict[str, list[BandWeights]]:
    """Model-SRF weights of every variant of each band."""
    return {name: [setup.weights(name, c, w) for c, w in var] for name, var in variants.items()}


class Truth:
    """Noisy band radiances of every target × true column × pixel, per band variant. Band ``k`` of
    ``variants`` (its slot) keys the noise stream of all its variants."""

    def __init__(self, setup: StudySetup, profile: str, variants: dict[str, np.ndarray],
                 weights: dict[str, list[BandWeights]], targets: dict[str, SpectralLibrary]):
        st = setup.study
        spectra = np.concatenate([lib.spectra for lib in targets.values()])
        self.labels = np.concatenate([[k] * lib.size for k, lib in targets.items()])
        self.truth = np.array(st.water_vapour)
        per_state = []
        for wv in st.water_vapour:
            per_state.append(setup.terms(setup.truth(profile=profile, water_vapour=wv)).toa_radiance(spectra))
        toa = np.stack(per_state, axis=1)  # (n_spectra, n_wv, n_wl)
        self.radiance: dict[str, np.ndarray] = {}
        for slot, (name, var) in enumerate(variants.items()):
            L = np.stack([apply(wt, toa).ravel() for wt in weights[name]])
            bands = [setup.band(name).with_shape(c, w) for c, w in var]
            self.radiance[name] = noisy(setup, bands, L, [slot] * len(var), st.pixels).reshape(
                len(var), spectra.shape[0], len(st.water_vapour), st.pixels)


def reference(L8: np.ndarray, t8: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """A window channel's part of the continuum from its radiances ``L8 (...)`` on the axis, each ``(..., n)``:
    its reflectance ρ corrected at each node and its path-corrected radiance ``L8 − Lp8``."""
    L8 = L8[..., None]
    return inverse(**t8, radiance=L8), L8 - t8["lp"]


def continuum(refs: Sequence[tuple[np.ndarray, np.ndarray]], weights: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
    """The surface continuum at the absorption band from window channels (:func:`reference` of each) and their
    interpolation weights (summing to 1): ``(Σ a_k ρ_k, Σ a_k (L_k − Lp_k))``."""
    rho = sum(a * r for a, (r, _) in zip(weights, refs, strict=True))
    d = sum(a * dk for a, (_, dk) in zip(weights, refs, strict=True))
    return rho, d


def interpolation_weights(window_nm: Sequence[float], absorption_nm: float) -> list[float]:
    """Weights of one or two window channels (centres, nm) whose sum is the continuum at ``absorption_nm``:
    ``[1]`` for one window; linear in wavelength between two (Schläpfer et al. 1998)."""
    if len(window_nm) == 1:
        return [1.0]
    lo, hi = window_nm
    a_hi = (absorption_nm - lo) / (hi - lo)
    return [1.0 - a_hi, a_hi]


def apda_difference(L9: np.ndarray, t9: dict[str, np.ndarray], cont: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Measured minus modelled APDA ratio of absorption-band radiances ``L9 (...)`` against a continuum ``cont`` =
    (ρ_c, d_c) on the axis (:func:`continuum`), ``(..., n)``: the ratio ``(L9 − Lp9) / d_c`` and its model
    ``G9·ρ_c / (1 − S9·ρ_c) / d_c``, a surface whose reflectance at the absorption band is ρ_c."""
    rho, d = cont
    L9 = L9[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = (L9 - t9["lp"]) / d
        model = t9["g"] * rho / (1 - t9["s"] * rho) / d
    return ratio - model


def retrieve_continuum(L9: np.ndarray, t9: dict[str, np.ndarray], axis: np.ndarray,
                       cont: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """APDA water vapour (g/cm²): the crossing of :func:`apda_difference` with zero along ``axis`` (linear in √w)."""
    return crossing(np.sqrt(axis), apda_difference(L9, t9, cont)) ** 2


def retrieve(L9: np.ndarray, L8: np.ndarray, t9: dict[str, np.ndarray], t8: dict[str, np.ndarray],
             axis: np.ndarray, ref: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Two-channel APDA water vapour (g/cm²) of radiances ``L9, L8 (...)`` from band terms on ``axis`` (each
    ``(n,)``): the continuum is the B8a reflectance; ``ref`` is :func:`reference` of ``L8, t8`` where the caller
    has it already."""
    return retrieve_continuum(L9, t9, axis, ref if ref is not None else reference(L8, t8))


def lut_terms(setup: StudySetup, profile: str, axis: np.ndarray,
               weights: dict[str, list[BandWeights]]) -> dict[str, list[dict[str, np.ndarray]]]:
    """Band terms (lp, g, s over ``axis``) of every variant of each band, assumed state with ``profile``."""
    terms = [setup.terms(setup.assumed(profile=profile, water_vapour=w)) for w in axis]
    return {name: band_terms(terms, wts) for name, wts in weights.items()}


def scores(wv: np.ndarray, truth: Truth) -> dict[str, float]:
    """Relative RMS (%) per target class and over all."""
    t = truth.truth[None, :, None]
    out = {lab: 100 * rel_rms(wv[truth.labels == lab], t) for lab in dict.fromkeys(truth.labels)}
    out["all"] = 100 * rel_rms(wv, t)
    return out


#: a retrieval of the winter case: (noisy radiances per band, band terms per band) → water vapour (g/cm²)
Retrieval = Callable[[dict[str, np.ndarray], dict[str, list[dict[str, np.ndarray]]]], np.ndarray]


def winter_scores(setup: StudySetup, axis: np.ndarray, variants: dict[str, np.ndarray],
                  weights: dict[str, list[BandWeights]], summer_lut: dict[str, list[dict[str, np.ndarray]]],
                  targets: dict[str, SpectralLibrary],
                  retrievals: dict[str, Retrieval]) -> dict[str, dict[str, dict[str, float]]]:
    """Winter scenes (MLW truth) of one variant per band, retrieved with the winter and with the summer LUT terms
    (``summer_lut``: the summer terms of those variants): retrieval name → LUT profile → :func:`scores`. All
    retrievals see the same noisy pixels."""
    truth = Truth(setup, WINTER, variants, weights, targets)
    luts = {WINTER: lut_terms(setup, WINTER, axis, weights), SUMMER: summer_lut}
    return {name: {p: scores(r(truth.radiance, luts[p]), truth) for p in (WINTER, SUMMER)}
            for name, r in retrievals.items()}


def run(setup: StudySetup) -> StudyResult:
    space = setup.space()
    variants = {b: space.per_band[k] for k, b in enumerate(space.bands)}
    weights = band_weights(setup, variants)
    targets = setup.targets()
    axis = wv_axis(setup)
    truth = Truth(setup, SUMMER, variants, weights, targets)
    lut = lut_terms(setup, SUMMER, axis, weights)
    refs = [reference(L8, t8) for L8, t8 in zip(truth.radiance["B8a"], lut["B8a"], strict=True)]
    idx = space.indices(0, space.size)
    per_config = []
    for i9, i8 in idx:
        wv = retrieve(truth.radiance["B9"][i9], truth.radiance["B8a"][i8], lut["B9"][i9], lut["B8a"][i8], axis,
                      refs[i8])
        per_config.append(scores(wv, truth))
    classes = list(per_config[0])
    shapes = space.shapes(0, space.size)
    k = setup.nominal(space)
    # winter scenes, nominal bands
    i9, i8 = idx[k]
    nom = {"B9": [i9], "B8a": [i8]}
    nom_vars = {b: variants[b][i] for b, i in nom.items()}
    nom_weights = {b: [weights[b][i] for i in nom[b]] for b in nom}

    def two_channel(rad: dict[str, np.ndarray], lt: dict[str, list[dict[str, np.ndarray]]]) -> np.ndarray:
        return retrieve(rad["B9"][0], rad["B8a"][0], lt["B9"][0], lt["B8a"][0], axis)

    winter = winter_scores(setup, axis, nom_vars, nom_weights, {b: [lut[b][i] for i in nom[b]] for b in nom},
                           targets, {"two": two_channel})["two"]

    def label(j: int) -> list[str]:
        return [f"{shapes[j, 0, 0]:g}/{shapes[j, 0, 1]:g}", f"{shapes[j, 1, 0]:g}/{shapes[j, 1, 1]:g}"]

    order = np.argsort([s["all"] for s in per_config])
    shown: list[tuple[str, int]] = []
    shown.append(("ESA nominal", k))
    for j in range(space.size):   # B8a shifts with the nominal B9
        if j != k and np.allclose(shapes[j, 0], shapes[k, 0]):
            shown.append(("B8a shift", j))
    for j in range(space.size):   # B9 at 920 nm (nominal width) with the nominal B8a
        if np.allclose(shapes[j, 1], shapes[k, 1]) and np.allclose(shapes[j, 0], (920.0, shapes[k, 0, 1])):
            shown.append(("B9 at 920", j))
    shown += [(f"best #{r + 1}", int(j)) for r, j in enumerate(order[:5])]
    rows = [[tag, *label(j), *(f"{per_config[j][c]:.2f}" for c in classes)] for tag, j in shown]
    rows.append(["winter, winter LUT", *label(k), *(f"{winter[WINTER][c]:.2f}" for c in classes)])
    rows.append(["winter, summer LUT", *label(k), *(f"{winter[SUMMER][c]:.2f}" for c in classes)])
    ref = per_config[k]
    b8a = [j for tag, j in shown if tag == "B8a shift"]
    rel_increase = {c: 100 * (winter[SUMMER][c] / winter[WINTER][c] - 1) for c in classes}
    figures = [KeyFigure(f"relative RMS of WV, B9 {shapes[k, 0, 0]:g}/{shapes[k, 0, 1]:g} + B8a "
                         f"{shapes[k, 1, 0]:g}/{shapes[k, 1, 1]:g}, {c}", round(ref[c], 2),
                         float(np.mean(PAPER_RMS_PCT)), "%", "paper: 5–10 % for its test scenes")
               for c in classes]
    if b8a:
        best = min(b8a, key=lambda j: per_config[j]["all"])
        figures.append(KeyFigure(f"best B8a shift ({label(best)[1]}) minus nominal, all targets",
                                 round(per_config[best]["all"] - ref["all"], 2), None, "pp",
                                 "paper: no significant improvement"))
    figures += [KeyFigure(f"winter scenes with the summer LUT: RMS increase, {c}", round(rel_increase[c], 1),
                          PAPER_WINTER_INCREASE_PCT, "% of the RMS",
                          f"{winter[WINTER][c]:.2f} → {winter[SUMMER][c]:.2f} %; paper: +6 %") for c in classes]
    data = {
        "water_vapour_true": list(setup.study.water_vapour), "retrieval_axis": axis.tolist(),
        "targets": {k2: lib.names for k2, lib in targets.items()}, "pixels": setup.study.pixels,
        "bands": space.bands, "configurations": shapes.tolist(), "nominal_configuration": int(k),
        "table_configurations": [[tag, int(j)] for tag, j in shown],   # the table's rows: case, configuration
        "rel_rms_pct": {c: [s[c] for s in per_config] for c in classes},
        "winter": {"configuration": shapes[k].tolist(), "winter_lut": winter[WINTER], "summer_lut": winter[SUMMER],
                   "relative_increase_pct": rel_increase},
    }

    return StudyResult(
        title="B9 water vapour (APDA, B8a reference): relative RMS of retrieved WV (%)",
        columns=["case", "B9 c/w", "B8a c/w", *classes], rows=rows, key_figures=figures, data=data,
        notes=[f"true WV {', '.join(f'{w:g}' for w in setup.study.water_vapour)} g/cm²; "
               f"{setup.study.pixels} noisy pixels per target and column; retrieval assumes ρ(B9) = ρ(B8a)."])
