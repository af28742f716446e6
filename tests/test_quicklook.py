"""The quicklook's true-colour panel: each channel stretched from its 2nd to its 98th percentile, by hand, and the
stretch stated on the figure."""

from __future__ import annotations

import numpy as np

from s2cl.app import image_quicklook
from s2cl.app.image_quicklook import true_colour, write_quicklook
from s2cl.io.image_store import MemoryStore


def _store(b4: np.ndarray, b3: np.ndarray, b2: np.ndarray) -> MemoryStore:
    store = MemoryStore()
    ny, nx = b4.shape
    store.dimension("y_10m", np.arange(ny) + 0.5, {})
    store.dimension("x_10m", np.arange(nx) + 0.5, {})
    store.dimension("y_20m", np.arange(ny // 2) + 0.5, {})
    store.dimension("x_20m", np.arange(nx // 2) + 0.5, {})
    for name, values in (("B4", b4), ("B3", b3), ("B2", b2)):
        store.create(f"reflectance_{name}", ("y_10m", "x_10m"), np.float32, {})
        store.write(f"reflectance_{name}", slice(0, ny), values.astype(np.float32))
    store.create("analysis_index", ("y_20m", "x_20m"), np.float32, {"units": "nm"})
    store.write("analysis_index", slice(0, ny // 2), np.full((ny // 2, nx // 2), 720.0, np.float32))
    store.create("analysis_status", ("y_20m", "x_20m"), np.uint8, {})
    return store


def test_each_channel_is_stretched_from_its_2nd_to_its_98th_percentile() -> None:
    """Red holds 0 … 99 (percentiles 1.98 and 97.02: numpy's linear rule, 99 × 0.02 and 99 × 0.98 places in), green
    the same × 0.1 + 0.05, blue a constant (no spread: left as it is, clipped to 0 … 1)."""
    red = np.arange(100.0).reshape(10, 10) / 100
    green = red * 0.1 + 0.05
    blue = np.full((10, 10), 0.5)
    rgb = true_colour(_store(red, green, blue))
    lo, hi = 0.0198, 0.9702
    np.testing.assert_allclose(rgb[..., 0], np.clip((red - lo) / (hi - lo), 0, 1), atol=1e-6)
    np.testing.assert_allclose(rgb[..., 1], np.clip((green - (lo * 0.1 + 0.05)) / ((hi - lo) * 0.1), 0, 1),
                               atol=1e-5)
    np.testing.assert_allclose(rgb[..., 2], 0.0)
    assert rgb[0, 1, 0] == 0.0 and rgb[9, 9, 0] == 1.0  # 0.01 below the 2nd percentile, 0.99 above the 98th


def test_pixels_not_finite_everywhere_stay_out_of_the_percentiles() -> None:
    red = np.arange(100.0).reshape(10, 10) / 100
    red_nan = red.copy()
    red_nan[0, :5] = np.nan  # five pixels without a red value: the percentiles of the other 95, by hand below
    rgb = true_colour(_store(red_nan, red, red))
    kept = np.arange(5, 100) / 100
    lo, hi = np.interp(0.02 * 94, np.arange(95), kept), np.interp(0.98 * 94, np.arange(95), kept)
    np.testing.assert_allclose(rgb[..., 1][1:], np.clip((red[1:] - lo) / (hi - lo), 0, 1), atol=1e-6)
    assert np.isnan(rgb[0, :5, 0]).all()


def test_the_stretch_is_stated_on_the_figure(tmp_path, monkeypatch) -> None:
    """What write_quicklook hands to the PNG writer: the true-colour panel's title names the bands and the stretch."""
    seen = {}

    def capture(fig, path, dpi=100):
        seen["titles"] = [ax.get_title() for ax in fig.axes]
        return path

    monkeypatch.setattr(image_quicklook, "save_png", capture)
    red = np.arange(100.0).reshape(10, 10) / 100
    write_quicklook(_store(red, red, red), tmp_path / "q.png")
    assert seen["titles"][0] == "true colour (B4 B3 B2)\nL2 reflectance, each channel stretched 2–98 %"
