"""The 2.1 µm cellulose band (paper Sec. 5, beyond the paper): how well each design of a narrow band near
2.1 µm, inside CO₂ absorption, estimates the non-photosynthetic-vegetation fraction against what
Sentinel-2 has today.

Truth: linear mixtures of soil, NPV and (a little) green vegetation from [study] ``targets`` (``soil``,
``npv``, ``green``; :func:`s2cl.studies.npv.linear_mixtures`) at the fractions ``npv_fractions`` ×
``green_fractions``, under the [atmosphere] state with every true water column of [study] ``water_vapour``
(default: the [atmosphere]'s) and every CO₂ column factor of ``co2_factors`` (the LUT's fixed CO₂ scaled,
:meth:`s2cl.atmos.terms.AtmosphericTerms.with_gas_column`) → band radiance (model SRF, eq. 1) → sensor
noise (:func:`s2cl.studies.common.noisy`: each band's SNR-table model at its width, ``pixels`` noisy
copies, the sense kernel's Philox deviates keyed by band slot, so every 2.1 µm variant sees the same draws)
→ band-effective correction with the assumed state ([correction] over [atmosphere], CO₂ factor 1).

Bands: the 2.1 µm band is swept as variants of B12 (the [sweep] grid of centres × widths: B12's SWIR
detector, its SNR rule scaled with width); the CAI's two shoulders ([study] ``shoulders``) are fixed B12
variants too. Retrieval: ``f_NPV = a + b·CAI`` by least squares over all pixels of a design
(:func:`s2cl.retrieve.quantify.fit_polynomial`, degree 1); score: RMS of f_NPV. Base: the same regression on
NDTI of the nominal B11 and B12, same pixels and noise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from s2cl.atmos.terms import AtmosphericTerms
from s2cl.errors import InputError
from s2cl.retrieve.quantify import PolyFit, fit_polynomial
from s2cl.sensor.noise_model import noise_sigma
from s2cl.sensor.sensor import Band
from s2cl.sensor.srf import BandWeights
from s2cl.studies.common import KeyFigure, StudyResult, StudySetup, apply, band_terms, inverse, noisy
from s2cl.studies.npv import Mixtures, band_radiance, cai, gas_signal_fraction, linear_mixtures, ndti

SWEPT = "B12"          # the 2.1 µm band and the CAI shoulders are variants of B12 (SWIR-2 detector)
BASE = ("B11", "B12")  # NDTI, at the sensor's own shapes
CO2 = "carbon_dioxide"
LABELS = ("soil", "npv", "green")
#: what the study needs: bands in [sweep], non-empty [study] lists (checked by s2cl.studies.run_study)
NEEDS_BANDS, NEEDS_KEYS = (SWEPT,), ("npv_fractions", "shoulders", "targets")
#: noise slots (band ids of the Philox deviates): low shoulder, 2.1 µm band, high shoulder, B11, B12
SLOT_LOW, SLOT_21, SLOT_HIGH, SLOT_B11, SLOT_B12 = range(5)


@dataclass(frozen=True)
class Score:
    """One index regressed on f_NPV (unitless fractions): the whole chain (noisy pixels), the chain without
    noise, and the band reflectance of the surface alone (no atmosphere, no noise)."""

    rms: float
    r2: float
    rms_noise_free: float
    rms_surface: float
    fit: PolyFit


class _Chain:
    """The mixtures through the truth states, noise and the correction, one band at a time."""

    def __init__(self, setup: StudySetup, mixtures: Mixtures):
        st = setup.study
        self.setup, self.mix, self.pixels = setup, mixtures, st.pixels
        wvs = st.water_vapour or [setup.truth().water_vapour]
        self.states = [(float(wv), float(k)) for wv in wvs for k in st.co2_factors]
        self.true_terms: list[AtmosphericTerms] = [
            setup.terms(setup.truth(water_vapour=wv)).with_gas_column(CO2, k) for wv, k in self.states]
        self.assumed = setup.terms(setup.assumed())
        f = np.tile(mixtures.f_npv, len(self.states))          # (n_states · n_mix,)
        self.f_noisy = np.repeat(f, self.pixels)
        #: true f_NPV of the three outputs of :meth:`reflectance`
        self.truth = (self.f_noisy, f, mixtures.f_npv)

    def reflectance(self, band: Band, weights: BandWeights, slot: int) -> tuple[np.ndarray, ...]:
        """Band reflectance: corrected, of every pixel (noisy, ``(n_states · n_mix · pixels,)``); corrected, of
        every mixture and state without noise (``(n_states · n_mix,)``); of the surface (``(n_mix,)``)."""
        L = np.concatenate([band_radiance(t, self.mix.reflectance, weights) for t in self.true_terms])
        t = band_terms([self.assumed], [weights])[0]
        noisy_L = noisy(self.setup, [band], L[None], [slot], self.pixels)[0]
        surface = apply(weights, self.mix.reflectance)
        return inverse(**t, radiance=noisy_L).ravel(), inverse(**t, radiance=L), surface

    def ne_delta_rho(self, band: Band, weights: BandWeights) -> float:
        """Noise-equivalent reflectance (unitless) at the mixtures' mean band radiance: σ(L̄) / G_band."""
        L = np.concatenate([band_radiance(t, self.mix.reflectance, weights) for t in self.true_terms])
        a, b = band.noise_coefficients()
        g = band_terms([self.assumed], [weights])[0]["g"]
        return float(noise_sigma(L.mean(), a, b) / g[0])


def score(truth: tuple[np.ndarray, ...], index: Callable[..., np.ndarray], *bands: tuple[np.ndarray, ...]) -> Score:
    """Linear regression of f_NPV on ``index`` of the bands' reflectances, each band a triple (noisy pixels,
    noise-free, surface: :meth:`_Chain.reflectance`), against the matching true fractions ``truth``
    (:attr:`_Chain.truth`)."""
    fits = [fit_polynomial(index(*(b[k] for b in bands)), f, degree=1) for k, f in enumerate(truth)]
    return Score(fits[0].rms, fits[0].r2, fits[1].rms, fits[2].rms, fits[0])


def check(setup: StudySetup, variants: np.ndarray) -> None:
    """The [study] and [sweep] sections make sense for this study, before any work.

    :raises InputError: naming the key: target labels, fractions that add up to more than 1, a 2.1 µm
        centre outside the shoulders.
    """
    st, src = setup.study, setup.source
    unknown = sorted(set(st.targets) - set(LABELS))
    missing = [lab for lab in ("soil", "npv") if lab not in st.targets]
    if unknown or missing:
        what = f"unknown target {unknown[0]!r}" if unknown else f"no {missing[0]!r} target"
        raise InputError(f"{what}; the cellulose study takes soil, npv and (optional) green libraries",
                         source=src, key="study.targets")
    if max(st.green_fractions) > 0 and "green" not in st.targets:
        raise InputError("green fractions above 0 need a 'green' target library", source=src,
                         key="study.targets")
    if max(st.npv_fractions) + max(st.green_fractions) > 1 + 1e-12:
        raise InputError(f"the largest NPV fraction ({max(st.npv_fractions):g}) and green fraction "
                         f"({max(st.green_fractions):g}) add up to more than 1", source=src,
                         key="study.green_fractions")
    (lo, _), (hi, _) = st.shoulders
    outside = [c for c in variants[:, 0] if not lo < c < hi]
    if outside:
        raise InputError(f"the 2.1 µm band centre {outside[0]:g} nm must lie between the shoulders' centres "
                         f"({lo:g} and {hi:g} nm)", source=src, key=f"sweep.ranges.{SWEPT}")


def _weights(setup: StudySetup, band: Band, key: str) -> BandWeights:
    """Model-SRF weights of ``band`` on the scene's grid; a band outside the grid names ``key``."""
    try:
        return band.weights(setup.scene.grid, setup.scene.run.support, setup.source)
    except InputError as err:
        raise InputError(f"{band.centre_nm:g}/{band.fwhm_nm:g} nm: {err.detail}", source=setup.source,
                         key=key) from None


def mixtures(setup: StudySetup) -> tuple[Mixtures, dict[str, np.ndarray]]:
    """The study's linear mixtures from its target libraries (NaN in a library is refused), and each
    library's mean spectrum (for the figure)."""
    st = setup.study
    libs = setup.targets()
    for label, lib in libs.items():
        if not np.isfinite(lib.spectra).all():
            raise InputError(f"library {st.targets[label]!r} has missing values on the scene's grid "
                             f"{setup.scene.grid.describe()}", source=setup.source, key=f"study.targets.{label}")
    green = libs["green"].spectra if "green" in libs else None
    mix = linear_mixtures(libs["soil"].spectra, libs["npv"].spectra, green, st.npv_fractions, st.green_fractions)
    return mix, {label: lib.spectra.mean(axis=0) for label, lib in libs.items()}


def run(setup: StudySetup) -> StudyResult:
    st = setup.study
    space = setup.space()
    variants = space.per_band[space.bands.index(SWEPT)]
    check(setup, variants)
    base_band = setup.band(SWEPT)
    shoulders = [base_band.with_shape(c, w) for c, w in st.shoulders]
    sh_w = [_weights(setup, b, "study.shoulders") for b in shoulders]
    var_bands = [base_band.with_shape(c, w) for c, w in variants]
    var_w = [_weights(setup, b, f"sweep.ranges.{SWEPT}") for b in var_bands]
    base = [setup.band(n) for n in BASE]
    base_w = [_weights(setup, b, "sensor.bands") for b in base]
    mix, means = mixtures(setup)
    chain = _Chain(setup, mix)

    lo = chain.reflectance(shoulders[0], sh_w[0], SLOT_LOW)
    hi = chain.reflectance(shoulders[1], sh_w[1], SLOT_HIGH)
    scores, co2_signal, nedr = [], [], []
    for band, wt in zip(var_bands, var_w, strict=True):
        scores.append(score(chain.truth, cai, lo, chain.reflectance(band, wt, SLOT_21), hi))
        co2_signal.append(gas_signal_fraction(chain.assumed, CO2, wt))
        nedr.append(chain.ne_delta_rho(band, wt))
    base_score = score(chain.truth, ndti, *(chain.reflectance(b, w, slot)
                                      for b, w, slot in zip(base, base_w, (SLOT_B11, SLOT_B12), strict=True)))
    shoulder_co2 = [gas_signal_fraction(chain.assumed, CO2, w) for w in sh_w]
    return _result(setup, chain, variants, scores, co2_signal, nedr, base_score, shoulder_co2, means)


def _result(setup: StudySetup, chain: _Chain, variants: np.ndarray, scores: list[Score], co2_signal: list[float],
            nedr: list[float], base: Score, shoulder_co2: list[float], means: dict[str, np.ndarray]) -> StudyResult:
    st = setup.study
    rms = np.array([s.rms for s in scores])
    order = np.argsort(rms)
    widths = sorted(set(variants[:, 1].tolist()))
    best_per_width = [min(np.flatnonzero(variants[:, 1] == w), key=lambda j: rms[j]) for w in widths]
    shown = [(f"best #{r + 1}", int(j)) for r, j in enumerate(order[:3])]
    shown += [(f"best {w:g} nm wide", int(j)) for w, j in zip(widths, best_per_width, strict=True)]

    def row(tag: str, j: int) -> list[str]:
        s = scores[j]
        return [tag, f"{variants[j, 0]:g}/{variants[j, 1]:g}", f"{100 * (1 - co2_signal[j]):.1f}", f"{nedr[j]:.4f}",
                f"{s.rms:.4f}", f"{s.r2:.3f}", f"{s.rms_noise_free:.4f}", f"{s.rms_surface:.4f}"]

    rows = [row(tag, j) for tag, j in shown]
    rows.append(["base: NDTI (B11, B12)", "–", "–", "–", f"{base.rms:.4f}", f"{base.r2:.3f}",
                 f"{base.rms_noise_free:.4f}", f"{base.rms_surface:.4f}"])
    k = int(order[0])
    narrow = int(best_per_width[0])
    wide = int(best_per_width[-1])
    figures = [
        KeyFigure(f"best 2.1 µm design {variants[k, 0]:g}/{variants[k, 1]:g} nm: RMS of f_NPV (CAI)",
                  round(float(rms[k]), 4), None, "fraction", "paper: a narrow band is needed"),
        KeyFigure("base: NDTI of B11 and B12, RMS of f_NPV", round(base.rms, 4), None, "fraction",
                  "what Sentinel-2 has today"),
        KeyFigure(f"narrowest ({variants[narrow, 1]:g} nm, best centre {variants[narrow, 0]:g}): RMS of f_NPV",
                  round(float(rms[narrow]), 4), None, "fraction",
                  f"noise-free {scores[narrow].rms_noise_free:.4f}; CO2 takes {100 * (1 - co2_signal[narrow]):.1f} %"),
        KeyFigure(f"widest ({variants[wide, 1]:g} nm, best centre {variants[wide, 0]:g}): RMS of f_NPV",
                  round(float(rms[wide]), 4), None, "fraction",
                  f"noise-free {scores[wide].rms_noise_free:.4f}; CO2 takes {100 * (1 - co2_signal[wide]):.1f} %"),
    ]
    wl = setup.scene.grid.wavelengths
    sel = (wl >= 1950) & (wl <= 2300)
    mix = chain.mix
    data = {
        "variants": variants.tolist(), "rms": rms.tolist(), "r2": [s.r2 for s in scores],
        "rms_noise_free": [s.rms_noise_free for s in scores], "rms_surface": [s.rms_surface for s in scores],
        "co2_signal_fraction": co2_signal,
        "ne_delta_rho": nedr, "best": int(k), "table_configurations": [[tag, j] for tag, j in shown],
        "base": {"index": "NDTI", "bands": list(BASE), "rms": base.rms, "r2": base.r2,
                 "rms_noise_free": base.rms_noise_free, "rms_surface": base.rms_surface},
        "shoulders": [list(s) for s in st.shoulders], "shoulder_co2_signal_fraction": shoulder_co2,
        "best_fit": {"intercept": float(scores[k].fit.coefficients_in_index()[0]),
                     "slope_per_cai": float(scores[k].fit.coefficients_in_index()[1])},
        "states": [{"water_vapour": wv, "co2_factor": c} for wv, c in chain.states],
        "assumed": {"water_vapour": chain.assumed.state.water_vapour, "co2_factor": 1.0},
        "mixtures": mix.size, "pixels_per_mixture": st.pixels, "pixels": int(chain.f_noisy.size),
        "npv_fractions": list(st.npv_fractions), "green_fractions": list(st.green_fractions),
        "targets": dict(st.targets), "spectra_per_library": st.spectra,
        "wavelength_nm": wl[sel].tolist(),
        "co2_transmittance": chain.assumed.transmittance[CO2][sel].tolist(),
        "water_transmittance": chain.assumed.t_water[sel].tolist(),
        "mean_reflectance": {label: m[sel].tolist() for label, m in means.items()},
    }
    states = ", ".join(f"WV {wv:g} g/cm² × CO2 {c:g}" for wv, c in chain.states)
    return StudyResult(
        title="2.1 µm cellulose band: RMS of the NPV fraction from the CAI (linear regression)",
        columns=["case", "2.1 µm c/w nm", "CO2 signal loss %", "NEΔρ", "RMS f_NPV", "R²", "RMS no noise",
                 "RMS surface"],
        rows=rows, key_figures=figures, data=data,
        notes=[f"shoulders {' and '.join(f'{c:g}/{w:g}' for c, w in st.shoulders)} nm (B12 variants); "
               f"{mix.size} mixtures × {len(chain.states)} true states ({states}) × {st.pixels} noisy pixels; "
               f"correction assumes WV {chain.assumed.state.water_vapour:g} g/cm² and the LUT's CO2.",
               "CO2 signal loss: the share of the band's ground-reflected signal CO2 absorbs (6S's fixed profile)."])

