"""Shared pieces of the atmospheric-band studies: the study scene, band variants, band-effective
terms over a state axis, noise, and the result record that the CLI prints and writes.

Radiances are W m⁻² sr⁻¹ µm⁻¹, reflectances unitless, wavelengths nm, water vapour g/cm², ozone DU.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..atmosphere import AtmosphereLUT, AtmosphereState, AtmosphericTerms
from ..errors import InputError
from ..libraries import load_library
from ..library import SpectralLibrary
from ..reference.philox import sensor_noise
from ..scene import Scene, StudySpec
from ..sensor import Band
from ..srf import BandWeights
from ..sweep_tables import sweep_space
from ..variants import SweepSpace


@dataclass(frozen=True)
class KeyFigure:
    """One number of a study beside the paper's (``paper`` is None where the paper gives none)."""

    quantity: str
    s2cl: float
    paper: float | None
    unit: str
    note: str = ""


@dataclass
class StudyResult:
    """What a study produced: a table (rows of cells), key figures, JSON data and a plot function."""

    name: str
    title: str
    columns: list[str]
    rows: list[list[Any]]
    key_figures: list[KeyFigure]
    data: dict[str, Any]
    plot: Callable[[Path], Path]
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "study": self.name,
            "title": self.title,
            "table": {"columns": self.columns, "rows": self.rows},
            "key_figures": [vars(k) for k in self.key_figures],
            "notes": self.notes,
            "data": self.data,
        }


@dataclass(frozen=True)
class StudySetup:
    """A loaded study scene: the scene, its [study] section (``--quick`` applied) and the LUT."""

    scene: Scene
    study: StudySpec
    lut: AtmosphereLUT
    quick: bool

    @property
    def source(self) -> str:
        return self.scene.source

    def truth(self, **changes: Any) -> AtmosphereState:
        """The scene's [atmosphere] state, with ``changes``."""
        a = self.scene.spec.atmosphere
        aot = a.aot550 if a.aot550 is not None else AtmosphereState.from_visibility(a.visibility_km or 23.0).aot550
        state = AtmosphereState(profile=a.profile, water_vapour=a.water_vapour, aot550=aot, ozone=a.ozone,
                                solar_zenith=a.solar_zenith)
        return state.replace(**changes) if changes else state

    def assumed(self, **changes: Any) -> AtmosphereState:
        """The state the correction assumes: [correction] keys over [atmosphere], with ``changes``."""
        c = self.scene.spec.correction
        base = self.truth()
        keys = {k: getattr(c, k) for k in ("profile", "water_vapour", "aot550", "ozone", "solar_zenith")
                if getattr(c, k) is not None}
        if c.visibility_km is not None:
            keys["aot550"] = AtmosphereState.from_visibility(c.visibility_km).aot550
        return base.replace(**keys, **changes)

    def terms(self, state: AtmosphereState) -> AtmosphericTerms:
        try:
            return self.lut.terms(state, self.scene.grid, method=self.scene.spec.atmosphere.interpolation)
        except InputError as err:
            raise err.within(self.source, "study") from None

    def space(self) -> SweepSpace:
        """The [sweep] section as band variants (:mod:`s2cl.variants`)."""
        return sweep_space(self.scene).validate(self.source)

    def band(self, name: str) -> Band:
        return self.scene.sensor.band(name)

    def weights(self, name: str, centre_nm: float, width_nm: float) -> BandWeights:
        """Model-SRF weights (paper eq. 1) of band ``name`` moved to ``centre_nm``/``width_nm``."""
        return self.band(name).with_shape(centre_nm, width_nm).weights(
            self.scene.grid, self.scene.spec.sensor.support, self.source)

    def targets(self) -> dict[str, SpectralLibrary]:
        """Target classes from [study] ``targets`` (each library cut to ``spectra`` spectra)."""
        out = {}
        for label, name in self.study.targets.items():
            lib = load_library(name, self.scene.grid, source=self.source, key=f"study.targets.{label}")
            n = self.study.spectra
            if n and lib.size > n:
                lib = lib.subset(np.linspace(0, lib.size - 1, n).round().astype(int))
            out[label] = lib
        return out


def load_study(scene: Scene, quick: bool = False, lut: AtmosphereLUT | None = None) -> StudySetup:
    """Check that ``scene`` has a [study] section and apply its ``quick`` overrides."""
    spec = scene.spec.study
    if spec is None:
        raise InputError("the scene has no [study] section", source=scene.source, key="study")
    if quick and spec.quick:
        data = spec.model_dump()
        unknown = set(spec.quick) - set(data) | ({"kind", "quick"} & set(spec.quick))
        if unknown:
            raise InputError(f"quick cannot replace {', '.join(sorted(unknown))}", source=scene.source,
                             key="study.quick")
        data.update(spec.quick)
        data["quick"] = {}
        spec = StudySpec.model_validate(data)
    return StudySetup(scene=scene, study=spec, lut=lut or AtmosphereLUT.load(scene.spec.atmosphere.lut), quick=quick)


def apply(weights: BandWeights, spectrum: np.ndarray) -> np.ndarray:
    """SRF-weighted band value of ``spectrum (..., n_wl)``."""
    return spectrum[..., weights.start:weights.stop] @ weights.weights


def band_terms(terms: Sequence[AtmosphericTerms], weights: Sequence[BandWeights]) -> dict[str, np.ndarray]:
    """Band-effective Lp, G, S (as :class:`s2cl.correction.BandAtmosphere`) for each state × band:
    arrays ``(n_states, n_bands)``."""
    from ..correction import BandAtmosphere

    per = [BandAtmosphere.of(t, list(weights)) for t in terms]
    return {"lp": np.array([b.path_radiance for b in per]), "g": np.array([b.ground_term for b in per]),
            "s": np.array([b.spherical_albedo for b in per])}


def forward(lp: np.ndarray, g: np.ndarray, s: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Band-level forward model ``Lp + G·ρ/(1 − S·ρ)`` (broadcasting)."""
    return lp + g * rho / (1.0 - s * rho)


def inverse(lp: np.ndarray, g: np.ndarray, s: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """Band-level correction ``y/(1 + S·y)``, ``y = (L − Lp)/G`` (broadcasting)."""
    y = (radiance - lp) / g
    return y / (1.0 + s * y)


def noisy(setup: StudySetup, band: Band, width_nm: float, radiance: np.ndarray, band_id: int,
          pixels: int) -> np.ndarray:
    """``pixels`` noisy copies of each radiance ``(n,)`` → ``(n, pixels)``: the sensor's noise model
    (σ from its SNR table at this width) times the sense kernel's own Philox deviates (seed from
    [effects]); no noise when the scene switches noise off."""
    radiance = np.asarray(radiance, dtype=np.float64)
    if not setup.scene.effects.noise:
        return np.repeat(radiance[:, None], pixels, axis=1)
    idx = np.arange(radiance.size * pixels)
    z = sensor_noise(setup.scene.spec.effects.seed, idx, [band_id], setup.scene.spec.effects.frame)[0]
    sigma = band.noise.sigma(radiance, width_nm)
    return radiance[:, None] + sigma[:, None] * z.reshape(radiance.size, pixels)


def crossing(x: np.ndarray, f: np.ndarray) -> np.ndarray:
    """First zero of ``f`` along its last axis (sampled at increasing ``x``), linear between samples;
    clamped to ``x``'s ends where ``f`` does not change sign. ``f (..., n)`` → ``(...)``."""
    sign = np.signbit(f)
    change = sign[..., 1:] != sign[..., :-1]
    has = change.any(axis=-1)
    k = np.where(has, change.argmax(axis=-1), 0)
    f0 = np.take_along_axis(f, k[..., None], -1)[..., 0]
    f1 = np.take_along_axis(f, (k + 1)[..., None], -1)[..., 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.clip(np.where(f1 != f0, f0 / (f0 - f1), 0.0), 0.0, 1.0)
    inside = x[k] + t * (x[k + 1] - x[k])
    # no sign change: the end where |f| is smaller
    edge = np.where(np.abs(f[..., 0]) <= np.abs(f[..., -1]), x[0], x[-1])
    return np.where(has, inside, edge)


def rel_rms(estimate: np.ndarray, truth: np.ndarray | float) -> float:
    """sqrt(mean(((estimate − truth)/truth)²)), unitless."""
    e = (np.asarray(estimate, dtype=np.float64) - truth) / truth
    return float(np.sqrt(np.mean(e**2)))


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: Path) -> Path:
    """Write a matplotlib figure atomically as PNG and close it."""
    from ..output import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    pyplot().close(fig)
    return Path(path)
