"""The end-to-end chain the accuracy knobs are measured on: a Lib1 slice through the default scene
(PROSAIL canopies → 6S atmosphere → SRFs → noise → 12-bit DN → calibration → correction → IGRM
chlorophyll on B4 B5 B6 B8), built from ``scenes/default.toml`` with overrides, through s2cl's
public API (:class:`s2cl.Scene`, :class:`s2cl.Simulator`, :class:`s2cl.retrieve.igrm.IgrmFitter`,
:func:`s2cl.retrieve.quantify.score_igrm`).
"""

from __future__ import annotations

import copy
import time
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import check, interleaved_medians, max_rel_error
from s2cl import Scene, SpectralLibrary
from s2cl.app.chain_parts import scene_simulator
from s2cl.cl.runtime import get_runtime
from s2cl.reference.forward import resample, toa_radiance
from s2cl.retrieve.igrm import IgrmFitter, IgrmResult, IgrmSettings
from s2cl.retrieve.quantify import RetrievalScore, score_igrm
from s2cl.scene.library import scene_library
from s2cl.scene.scene import find_scene
from s2cl.scene.terms import scene_atmosphere
from s2cl.sensor.srf import BandWeights

BANDS = ("B4", "B5", "B6", "B8")  # the default scene's analysis (and sweep) bands, in wavelength order
#: converged float64 fits: the reference every fit setting is scored against
REFERENCE_FIT = IgrmSettings(tol=1e-10, max_iter=255, residual_floor=1e-12)
#: the all-accurate chain: float64 kernels, 1 nm grid, the SRF model on ± 3 FWHM (the widest the
#: 400-2500 nm grid holds for B8; the super-Gaussian is at its 1e-4 floor beyond ± 0.77 FWHM),
#: exact LUT nodes (the paper's standard atmosphere sits on the LUT's nodes), converged float64 fits
REFERENCE_OVERRIDES: dict[str, Any] = {"compute.precision": "float64", "grid.step_nm": 1.0, "sensor.support": 3.0}
REFERENCE_FIT_REAL = "float64"


@dataclass
class Context:
    """What every benchmark shares: size preset, repeats, the default scene and the Lib1 slice."""

    quick: bool
    repeat: int
    spectra: int  # Lib1 spectra in the slice (evenly spaced over the library)
    copies: int  # noisy copies per spectrum in the knob runs
    block: int  # distinct spectra (as pixels of an image) per block of the timed forward chain + fit
    loops: int  # blocks per timed call (time_pixels = block × loops; the same block, new noise)
    cache: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def make(cls, quick: bool, repeat: int | None = None) -> Context:
        """The suite's sizes (``--quick``: reduced); ``repeat`` overrides its number of timed repeats."""
        return cls(quick=quick, repeat=repeat or (7 if quick else 9), spectra=60 if quick else 120,
                   copies=50 if quick else 200, block=20_000, loops=5 if quick else 10)

    @property
    def time_pixels(self) -> int:
        return self.block * self.loops

    @cached_property
    def scene_path(self) -> Path:
        return find_scene("default")

    @cached_property
    def scene_toml(self) -> dict[str, Any]:
        """The default scene's TOML, parsed once (every :meth:`scene` works on a deep copy)."""
        return tomllib.loads(self.scene_path.read_text("utf-8"))

    def scene(self, *, all_bands: bool = False, **overrides: Any) -> Scene:
        """The default scene with ``{"section.key": value}`` overrides, simulating the analysis
        bands only unless ``all_bands``."""
        data = copy.deepcopy(self.scene_toml)
        if not all_bands:
            data.setdefault("sensor", {})["bands"] = list(BANDS)
        for dotted, value in overrides.items():
            section, key = dotted.split(".", 1)
            data.setdefault(section, {})[key] = value
        return Scene.from_dict(data, path=self.scene_path)

    def slice_index(self, size: int) -> np.ndarray:
        return np.unique(np.linspace(0, size - 1, min(self.spectra, size)).round().astype(int))

    def library_slice(self, scene: Scene, library: SpectralLibrary | None = None, *,
                      first: int | None = None) -> SpectralLibrary:
        """The Lib1 slice (``ctx.spectra`` spectra evenly spaced; the first ``first`` of them) of
        ``library``, by default the scene's own library."""
        lib = library if library is not None else scene_library(scene)
        return lib.subset(self.slice_index(lib.size)[:first])


def analysis_bands(scene: Scene, lib: SpectralLibrary, copies: int) -> tuple[list[int], np.ndarray, np.ndarray]:
    """The fit's inputs for ``scene``: the rows of B4 B5 B6 B8 among its bands, their centres (nm),
    and the chlorophyll of every pixel (each of ``lib``'s spectra ``copies`` times)."""
    rows = [scene.sensor.band_names.index(b) for b in BANDS]
    centres = np.array([scene.sensor.band(b).centre_nm for b in BANDS])
    target = np.repeat(np.asarray(lib.params["cab"], dtype=np.float64), copies)
    return rows, centres, target


def oracle_band_radiance(spectra: np.ndarray, terms: Any, weights: list[BandWeights] | tuple[BandWeights, ...]
                         ) -> np.ndarray:
    """The float64 numpy oracle: TOA radiance of reflectance ``spectra`` under the atmosphere
    ``terms`` (L = Lp + G·ρ/(1 − S·ρ) per wavelength), resampled with ``weights``: (bands, n)."""
    return resample(toa_radiance(spectra, terms.path_radiance, terms.ground_term, terms.spherical_albedo), weights)


@dataclass
class ChainRun:
    """One chain setting's outputs on the slice, and its timing."""

    label: str
    weights: tuple[BandWeights, ...]  # the chain's SRF weights per band (the Simulator's plan)
    band_radiance: np.ndarray  # (4, n_spectra) float64, noise-free TOA radiance
    sigma: np.ndarray  # (4, n_spectra) noise std (NER) at that radiance
    fit: IgrmResult
    score: RetrievalScore
    setup_seconds: float  # scene, library, atmosphere, kernels (cached builds)
    pixels: int  # timed pixels
    timer: Callable[[], None] | None = None  # one timed workload; dropped (with its arrays) once timed
    seconds: float = float("nan")  # median wall time of the workload (time_pixels through the chain + fit)

    def summary(self) -> dict[str, Any]:
        return {"seconds": self.seconds, "pixels_per_s": self.pixels / self.seconds,
                "setup_seconds": self.setup_seconds, "timed_pixels": self.pixels,
                "rms_cab": self.score.rms, "r2": self.score.r2, "frac_failed": self.score.frac_failed}


def noise_sigma(scene: Scene, radiance: np.ndarray) -> np.ndarray:
    return np.stack([b.noise.sigma(radiance[k], b.fwhm_nm) for k, b in enumerate(scene.sensor.bands)])


SEED = 1  # noise seed of every chain run


def run_chain(ctx: Context, label: str, overrides: dict[str, Any] | None = None, *,
              fit: IgrmSettings | None = None, fit_real: str = "float32", library: SpectralLibrary | None = None,
              divisor: np.ndarray | None = None, timed: bool = True) -> ChainRun:
    """Simulate the Lib1 slice with ``ctx.copies`` noisy copies under the default scene with
    ``overrides``, fit IGRM on B4 B5 B6 B8 and score chlorophyll (the accuracy). The run is not yet
    timed: :func:`time_runs` times the runs of a family together. The time is the median of
    ``ctx.time_pixels`` pixels (blocks of ``ctx.block`` distinct spectra, the slice tiled
    as pixels of an image: every pixel resampled) through the same compiled chain and fit.

    ``divisor`` (per band): the scene has no atmosphere and the library holds TOA radiance;
    reflectance is calibrated radiance / divisor (the atmosphere-off knob)."""
    copies = ctx.copies
    validated(ctx)
    t0 = time.perf_counter()
    scene = ctx.scene(**{"surface.copies": copies, **(overrides or {})})
    lib = ctx.library_slice(scene, library)
    sim = scene_simulator(get_runtime(), scene, atmosphere=scene_atmosphere(scene))
    fitter = IgrmFitter(get_runtime(), len(BANDS), fit or IgrmSettings(), real_t=fit_real)
    rows, centres, target = analysis_bands(scene, lib, copies)
    setup = time.perf_counter() - t0

    def reflectance(out: Any) -> np.ndarray:
        if divisor is None:
            return out.reflectance[rows]
        return out.calibrated[rows] / divisor[rows].reshape((-1,) + (1,) * (out.calibrated.ndim - 1))

    def once() -> tuple[Any, IgrmResult]:
        res = sim.run_library(lib, copies=copies, seed=SEED)
        return res, fitter.fit(reflectance(res).reshape(len(rows), -1), centres)

    res, r = once()
    n = ctx.time_pixels
    dtype = np.float64 if scene.run.precision == "float64" else np.float32
    pixels = np.ascontiguousarray(np.resize(lib.spectra, (ctx.block, lib.spectra.shape[1])), dtype=dtype)

    def image() -> None:
        for k in range(ctx.loops):
            radiance = sim.band_radiance(pixels)
            out = sim.sense(radiance, seed=SEED, pixel_offset=k * ctx.block)
            check(out is not None, "the chain does not sense (no noise, DN or correction stage)")
            fitter.fit(reflectance(out), centres)

    if timed:
        image()  # warm-up: first-enqueue compilation, buffer pools
    radiance = res.band_radiance.astype(np.float64)
    return ChainRun(label, sim.plan.weights, radiance, noise_sigma(scene, radiance), r, score_igrm(r, target), setup, n,
                    image if timed else None)


def time_runs(ctx: Context, *runs: ChainRun) -> None:
    """Time the runs of one family in interleaved rounds (drift hits all alike); frees their inputs."""
    todo = [r for r in runs if r.timer is not None]
    for r, sec in zip(todo, interleaved_medians([r.timer for r in todo], ctx.repeat), strict=True):  # type: ignore[misc]
        r.seconds, r.timer = sec, None


def reference_run(ctx: Context) -> ChainRun:
    """The all-accurate chain (validated against the float64 numpy oracles first); a fresh run per
    family, so that it is timed beside the family's settings."""
    return run_chain(ctx, "reference", REFERENCE_OVERRIDES, fit=REFERENCE_FIT, fit_real=REFERENCE_FIT_REAL)


def default_run(ctx: Context, timed: bool = True) -> ChainRun:
    """The default scene's settings (float32, 1 nm, support 1 FWHM, default fit), a fresh run."""
    return run_chain(ctx, "default", timed=timed)


def validated(ctx: Context) -> None:
    """Validate the chain once per process before the first timing (see :func:`validate_reference`)."""
    if "validation" not in ctx.cache:
        validate_reference(ctx)


def reference_vs_scipy(ours: IgrmResult, refl: np.ndarray, centres: np.ndarray) -> float:
    """The float64 kernel's converged fits ``ours`` of ``refl`` (bands, n) against
    scipy.optimize.least_squares at the same settings (:data:`REFERENCE_FIT`): at least 90 % fitted
    by both and lp within 1e-2 nm; returns the max |d lp| (nm)."""
    from s2cl.reference.igrm import fit_scipy

    theirs = fit_scipy(np.asarray(refl, dtype=np.float64), centres, REFERENCE_FIT)
    both = ours.fitted() & theirs.fitted()
    check(both.mean() > 0.9, f"float64 IGRM reference fits fail on {1 - both.mean():.1%} of the pixels")
    dlp = float(np.max(np.abs(ours.lp[both] - theirs.lp[both])))
    check(dlp < 1e-2, f"float64 IGRM reference disagrees with scipy least_squares: max |d lp| {dlp:.2e} nm")
    return dlp


def validate_reference(ctx: Context) -> None:
    """Before timing anything: the reference chain's kernels against the numpy float64 oracles on
    a small slice (TOA band radiance, and the IGRM fit against scipy.optimize.least_squares)."""
    scene = ctx.scene(**REFERENCE_OVERRIDES)
    lib = ctx.library_slice(scene, first=12)
    terms = scene_atmosphere(scene)
    check(terms is not None, "the reference scene has no atmosphere")
    sim = scene_simulator(get_runtime(), scene, atmosphere=terms)
    weights = sim.plan.weights
    err = max_rel_error(sim.band_radiance(lib.spectra), oracle_band_radiance(lib.spectra, terms, weights))
    check(err < 1e-10, f"float64 chain band radiance disagrees with the numpy oracle: max rel {err:.2e}")
    rows, centres, _ = analysis_bands(scene, lib, 1)
    refl = resample(lib.spectra, [weights[k] for k in rows])
    reference = IgrmFitter(get_runtime(), len(BANDS), REFERENCE_FIT, real_t="float64").fit(refl, centres)
    dlp = reference_vs_scipy(reference, refl, centres)
    ctx.cache["validation"] = {"reference_band_radiance_max_rel_vs_numpy": err, "reference_lp_vs_scipy_nm": dlp}


def compare(run: ChainRun, ref: ChainRun) -> dict[str, float]:
    """Accuracy lost against the reference: band radiance (relative and in noise units) and the
    final metric (per-pixel lp and the chlorophyll RMS)."""
    d = np.abs(run.band_radiance - ref.band_radiance)
    both = run.fit.fitted() & ref.fit.fitted()
    dlp = run.fit.lp[both].astype(np.float64) - ref.fit.lp[both]
    return {
        "err_radiance_rel_max": max_rel_error(run.band_radiance, ref.band_radiance),
        "err_radiance_ner_max": float(np.max(d / ref.sigma)),
        "err_lp_rms_nm": float(np.sqrt(np.mean(dlp**2))) if dlp.size else float("nan"),
        "err_rms_cab": abs(run.score.rms - ref.score.rms),
        "status_agreement": float(np.mean(run.fit.status == ref.fit.status)),
    }


def knob_row(setting: str, run: ChainRun, ref: ChainRun, *, default: bool = False,
             extra: dict[str, Any] | None = None) -> dict[str, Any]:
    return {"setting": setting, "default": default, **run.summary(), "speedup": ref.seconds / run.seconds,
            **compare(run, ref), **(extra or {})}


def slice_reflectance(ctx: Context) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Corrected band reflectance (4, n) float32 of the slice under the default scene, the band
    centres and the per-pixel chlorophyll: the input of the fit-setting knobs."""
    copies = ctx.copies
    validated(ctx)
    scene = ctx.scene(**{"surface.copies": copies})
    lib = ctx.library_slice(scene)
    sim = scene_simulator(get_runtime(), scene, atmosphere=scene_atmosphere(scene))
    res = sim.run_library(lib, copies=copies, seed=SEED)
    check(res.reflectance is not None, "the default scene does not correct to reflectance")
    rows, centres, target = analysis_bands(scene, lib, copies)
    return np.ascontiguousarray(res.reflectance[rows].reshape(len(rows), -1)), centres, target
