"""Plot a band's model SRF (paper eq. 1) against the measured Sentinel-2 response (the paper's Fig. 2)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from s2cl.io.plots import pyplot, save_png
from s2cl.sensor.sensor import Sensor
from s2cl.sensor.srf import DEFAULT_SUPPORT, measured_sentinel2_srf, super_gaussian


def plot_srf(band_name: str, platform: str | None, path: Path, sensor: Sensor | None = None) -> Path:
    """Model SRF (eq. 1, peak-normalised) of a band against the measured Sentinel-2 response."""
    plt = pyplot()
    band = (sensor or Sensor.sentinel2()).band(band_name)
    c, w = band.centre_nm, band.fwhm_nm
    wl = np.arange(c - 2 * w, c + 2 * w + 0.01, 0.1)
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    if platform:
        m = measured_sentinel2_srf(platform, band.name)
        ax.plot(m.wavelengths_nm, m.response / m.response.max(), "-", color="k", label=f"{platform} MSI measured")
    model = super_gaussian(wl, c, w)
    ax.plot(wl, model / model.max(), "--", color="tab:red", label="model, eq. (1)")
    for edge in (c - DEFAULT_SUPPORT * w, c + DEFAULT_SUPPORT * w):
        ax.axvline(edge, color="0.6", lw=0.8, ls=":")
    ax.set_xlim(c - 2 * w, c + 2 * w)
    ax.set_xlabel("wavelength (nm)")
    ax.set_ylabel("relative response")
    ax.set_title(f"Sentinel-2 {band.name}: centre {c:g} nm, FWHM {w:g} nm (dotted: support ±{DEFAULT_SUPPORT:g} FWHM)",
                 fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return save_png(fig, path)
