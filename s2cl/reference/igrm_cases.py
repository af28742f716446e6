"""Test and benchmark data for the IGRM fit: analytic curves with seeded noise, PROSAIL canopies.

Band reflectances are ``(n_bands, n_pixels)`` float64, band centres in nm. Nothing here is used
by the product code; tests and ``bench/`` share it so that both measure the same populations.
"""

from __future__ import annotations

import numpy as np

from s2cl.errors import DependencyError
from s2cl.reference.igrm import model

#: Sentinel-2 MSI red-edge bands (centre nm, FWHM nm) as used by ESA's preliminary design.
S2_RED_EDGE = {"B4": (665.0, 30.0), "B5": (705.0, 15.0), "B6": (740.0, 15.0), "B7": (783.0, 20.0),
               "B8": (842.0, 115.0), "B8a": (865.0, 20.0)}
BANDS_4 = ("B4", "B5", "B6", "B7")
BANDS_6 = ("B4", "B5", "B6", "B7", "B8", "B8a")

#: Parameter ranges of the synthetic population (a vegetation-like red edge).
SYNTHETIC_RANGES = {"rmax": (0.3, 0.6), "rmin": (0.01, 0.08), "l0": (665.0, 690.0), "s": (25.0, 50.0)}

#: PROSAIL inputs other than Cab and LAI (PROSPECT-D + 4SAIL, via the `prosail` package):
#: representative mean values of a green canopy, sun 30 deg off nadir, nadir view.
PROSAIL_FIXED = {"n": 1.5, "car": 8.0, "cbrown": 0.0, "cw": 0.01, "cm": 0.009, "lidfa": 57.0,
                 "hspot": 0.01, "tts": 30.0, "tto": 0.0, "psi": 0.0, "rsoil": 1.0, "psoil": 0.5}


def band_centres(names: tuple[str, ...]) -> np.ndarray:
    """Centres (nm) of the named S2 bands."""
    return np.array([S2_RED_EDGE[b][0] for b in names])


def synthetic(n: int, wavelengths_nm: np.ndarray, *, noise: float = 0.003, seed: int = 0) -> tuple[np.ndarray, dict]:
    """``n`` IGRM curves with parameters uniform in :data:`SYNTHETIC_RANGES` plus Gaussian noise
    of standard deviation ``noise`` (reflectance); returns (refl (n_bands, n), truth)."""
    rng = np.random.default_rng(seed)
    truth = {k: rng.uniform(lo, hi, n) for k, (lo, hi) in SYNTHETIC_RANGES.items()}
    clean = model(wavelengths_nm, truth["rmax"], truth["rmin"], truth["l0"], truth["s"])
    return clean + rng.normal(0.0, noise, clean.shape), truth


def box_resample(spectra: np.ndarray, names: tuple[str, ...], start_nm: float = 400.0) -> np.ndarray:
    """Box-average 1-nm spectra (n, n_wavelengths) starting at ``start_nm`` over each band's
    centre +- FWHM/2; returns (n_bands, n)."""
    spectra = np.atleast_2d(spectra)
    out = []
    for b in names:
        c, w = S2_RED_EDGE[b]
        lo, hi = round(c - w / 2 - start_nm), round(c + w / 2 - start_nm)
        out.append(spectra[:, lo:hi + 1].mean(axis=1))
    return np.array(out)


def prosail_canopies(cab: np.ndarray, lai: np.ndarray) -> np.ndarray:
    """PROSAIL top-of-canopy reflectance, 400-2500 nm at 1 nm, shape (n, 2101), for pairs
    (Cab ug/cm2, LAI m2/m2); other inputs :data:`PROSAIL_FIXED`."""
    try:
        import prosail
    except ImportError as err:
        raise DependencyError("PROSAIL spectra need the `prosail` package: pip install prosail") from err
    p = PROSAIL_FIXED
    return np.array([
        prosail.run_prosail(p["n"], float(c), p["car"], p["cbrown"], p["cw"], p["cm"], float(leaf_area), p["lidfa"],
                            p["hspot"], p["tts"], p["tto"], p["psi"], prospect_version="D",
                            rsoil=p["rsoil"], psoil=p["psoil"])
        for c, leaf_area in zip(np.atleast_1d(cab), np.atleast_1d(lai), strict=True)
    ])


def prosail_population(n: int, names: tuple[str, ...], *, noise: float = 0.003, seed: int = 0,
                       lai: tuple[float, ...] = (3.0, 4.0)) -> tuple[np.ndarray, dict]:
    """Lib1-like canopies (Cab 5-100 step 5 at each LAI) resampled to ``names``, each copied
    to reach ``n`` pixels with Gaussian noise; returns (refl (n_bands, n), {"cab", "lai"})."""
    cab_grid = np.arange(5.0, 101.0, 5.0)
    cab = np.repeat(cab_grid, len(lai))
    lais = np.tile(np.asarray(lai, dtype=float), cab_grid.size)
    bands = box_resample(prosail_canopies(cab, lais), names)
    idx = np.arange(n) % cab.size
    rng = np.random.default_rng(seed)
    return bands[:, idx] + rng.normal(0.0, noise, (len(names), n)), {"cab": cab[idx], "lai": lais[idx]}
