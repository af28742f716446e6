"""Shared pieces of the atmospheric-band studies: the study scene, band variants, band-effective
terms over a state axis, noise, and the result record that the CLI prints and writes.

Radiances are W m⁻² sr⁻¹ µm⁻¹, reflectances unitless, wavelengths nm, water vapour g/cm², ozone DU.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from s2cl.atmos.atmosphere import AtmosphereLUT
from s2cl.atmos.correction import BandAtmosphere, correct
from s2cl.atmos.state import AtmosphereState
from s2cl.atmos.terms import AtmosphericTerms
from s2cl.errors import InputError, errors_in
from s2cl.forward.noise import add_noise
from s2cl.forward.sense import Radiometry
from s2cl.libraries.library import SpectralLibrary
from s2cl.libraries.registry import load_library
from s2cl.scene.scene import Scene
from s2cl.scene.schema import StudySpec
from s2cl.scene.terms import assumed_state, scene_lut, state_terms, true_state
from s2cl.sensor.sensor import Band
from s2cl.sensor.srf import BandWeights
from s2cl.sensor.variants import SweepSpace
from s2cl.sweep.space import sweep_space


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
    """What a study produced: a table (rows of cells), key figures and JSON data. ``data`` is JSON-serialisable
    and holds all that the study's figure shows (:func:`s2cl.studies.plots.plot_study` draws it)."""

    title: str
    columns: list[str]
    rows: list[list[Any]]
    key_figures: list[KeyFigure]
    data: dict[str, Any]
    notes: list[str] = field(default_factory=list)

    def to_json(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "table": {"columns": self.columns, "rows": self.rows},
            "key_figures": [vars(k) for k in self.key_figures],
            "notes": self.notes,
            "data": self.data,
        }


@dataclass(frozen=True)
class StudySetup:
    """A loaded study scene: the scene and its [study] section (``--quick`` applied)."""

    scene: Scene
    study: StudySpec

    @property
    def source(self) -> str:
        return self.scene.source

    @property
    def lut(self) -> AtmosphereLUT:
        """The scene's LUT (:func:`s2cl.scene.terms.scene_lut`: path relative to the scene, cached)."""
        return scene_lut(self.scene)

    def truth(self, **changes: Any) -> AtmosphereState:
        """The scene's [atmosphere] state, with ``changes``."""
        return self._changed(true_state(self.scene), changes)

    def assumed(self, **changes: Any) -> AtmosphereState:
        """The state the correction assumes: [correction] keys over [atmosphere], with ``changes``."""
        return self._changed(assumed_state(self.scene), changes)

    def _changed(self, state: AtmosphereState, changes: dict[str, Any]) -> AtmosphereState:
        """``state`` with the study's ``changes``; an invalid one names ``study.KEY`` in the scene file."""
        try:
            return state.replace(**changes) if changes else state
        except InputError as err:
            raise err.within(self.source, "study") from None

    def terms(self, state: AtmosphereState) -> AtmosphericTerms:
        return state_terms(self.scene, state, "study")

    def space(self) -> SweepSpace:
        """The [sweep] section as band variants (:mod:`s2cl.sensor.variants`)."""
        scene = self.scene
        with errors_in(scene.source):
            space = sweep_space(scene.spec.sweep, scene.sensor, scene.grid, scene.run.support)
        return space.validate(self.source)

    def nominal(self, space: SweepSpace) -> int:
        """The configuration of ``space`` whose bands have the sensor's own shapes.

        :raises InputError: if the [sweep] section lacks one of them.
        """
        shapes = [(b.centre_nm, b.fwhm_nm) for b in map(self.band, space.bands)]
        k = space.find(shapes)
        if k is None:
            want = ", ".join(f"{n} {c:g}/{w:g}" for n, (c, w) in zip(space.bands, shapes, strict=True))
            raise InputError(f"the sweep lacks the nominal bands ({want} nm)", source=self.source, key="sweep")
        return k

    def band(self, name: str) -> Band:
        """Sensor band ``name``, else the [study] ``window2`` channel: the sensor band ``window2.noise_band``
        (its SNR model) renamed and moved to the headline centre/width."""
        w = self.study.window2
        sensor_band = name.lower() in (n.lower() for n in self.scene.sensor.band_names)
        if w is not None and not sensor_band and name.lower() == w.name.lower():
            try:
                template = self.scene.sensor.band(w.noise_band)
            except InputError as err:
                raise InputError(err.detail, source=self.source, key="study.window2.noise_band") from None
            return replace(template.with_shape(w.centre, w.width), name=w.name)
        return self.scene.sensor.band(name)

    def weights(self, name: str, centre_nm: float, width_nm: float) -> BandWeights:
        """Model-SRF weights (paper eq. 1) of band ``name`` moved to ``centre_nm``/``width_nm``."""
        return self.band(name).with_shape(centre_nm, width_nm).weights(
            self.scene.grid, self.scene.run.support, self.source)

    def targets(self) -> dict[str, SpectralLibrary]:
        """Target classes from [study] ``targets`` (each library cut to ``spectra`` spectra)."""
        out = {}
        for label, name in self.study.targets.items():
            lib = load_library(name, self.scene.grid, source=self.source, key=f"study.targets.{label}",
                               base_dir=self.scene.base_dir)
            n = self.study.spectra
            if n and lib.size > n:
                lib = lib.subset(np.linspace(0, lib.size - 1, n).round().astype(int))
            out[label] = lib
        return out


def load_study(scene: Scene, quick: bool = False) -> StudySetup:
    """Check that ``scene`` has a [study] section and apply its ``quick`` overrides."""
    spec = scene.spec.study
    if spec is None:
        raise InputError("the scene has no [study] section", source=scene.source, key="study")
    data = spec.model_dump()
    unknown = set(spec.quick) - set(data) | ({"kind", "quick"} & set(spec.quick))
    if unknown:   # checked on every run, not only under --quick
        raise InputError(f"quick cannot replace {', '.join(sorted(unknown))}", source=scene.source,
                         key="study.quick")
    if quick and spec.quick:
        data.update(spec.quick)
        data["quick"] = {}
        spec = StudySpec.model_validate(data)
    return StudySetup(scene=scene, study=spec)


def apply(weights: BandWeights, spectrum: np.ndarray) -> np.ndarray:
    """SRF-weighted band value of ``spectrum (..., n_wl)``."""
    return spectrum[..., weights.start:weights.stop] @ weights.weights


def band_terms(terms: Sequence[AtmosphericTerms], weights: Sequence[BandWeights]) -> list[dict[str, np.ndarray]]:
    """Band-effective Lp, G, S (:class:`s2cl.atmos.correction.BandAtmosphere`) of each band over a state
    axis: one dict per band with keys ``lp``, ``g``, ``s``, each ``(n_states,)``."""
    per = [BandAtmosphere.of(t, list(weights)) for t in terms]
    lp, g, s = (np.array([getattr(b, n) for b in per])
                for n in ("path_radiance", "ground_term", "spherical_albedo"))
    return [{"lp": lp[:, k], "g": g[:, k], "s": s[:, k]} for k in range(len(weights))]


def inverse(lp: np.ndarray, g: np.ndarray, s: np.ndarray, radiance: np.ndarray) -> np.ndarray:
    """Band-level correction (:func:`s2cl.atmos.correction.correct`, broadcasting)."""
    return correct(radiance, lp, g, s)


def noisy(setup: StudySetup, bands: Sequence[Band], radiance: np.ndarray, band_ids: Sequence[int],
          pixels: int) -> np.ndarray:
    """``pixels`` noisy copies of band radiances ``(n_bands, n)`` → ``(n_bands, n, pixels)``: the
    sensor's noise model at each band's width times the sense kernel's Philox deviates keyed by
    ``band_ids`` (:func:`s2cl.forward.noise.add_noise`, seed and frame from [effects]); no noise when
    the scene switches noise off."""
    radiance = np.asarray(radiance, dtype=np.float64)
    L = np.repeat(radiance, pixels, axis=1)
    if setup.scene.effects.noise:
        e = setup.scene.run
        r = Radiometry.of(list(bands), setup.scene.sensor.bits, list(band_ids))
        L = add_noise(L, r.noise_a, r.noise_b, r.band_ids, e.seed, frame=e.frame)
    return L.reshape(*radiance.shape, pixels)


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


def equal_error(eps: np.ndarray, rms: np.ndarray, level: float, side: int) -> float:
    """|ε| (unitless) on one side (+1 or −1) of ε = 0 where the RMS curve first reaches ``level``,
    linear between the sampled errors; NaN if it never does."""
    eps, rms = np.asarray(eps, dtype=np.float64), np.asarray(rms, dtype=np.float64)
    sel = np.flatnonzero(side * eps >= 0)
    order = sel[np.argsort(np.abs(eps[sel]))]
    x, y = np.abs(eps[order]), rms[order]
    above = np.flatnonzero(y >= level)
    if not above.size or above[0] == 0:
        return float("nan") if not above.size else float(x[0])
    i = above[0]
    return float(x[i - 1] + (level - y[i - 1]) * (x[i] - x[i - 1]) / (y[i] - y[i - 1]))
