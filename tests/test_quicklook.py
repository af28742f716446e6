"""The quicklook's true-colour panel: each channel stretched from its 2nd to its 98th percentile, by hand, and the
stretch stated on the figure."""

from __future__ import annotations

import itertools

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

    def capture(fig, path, **options):
        seen["titles"] = [ax.get_title() for ax in fig.axes]
        return path

    monkeypatch.setattr(image_quicklook, "save_png", capture)
    red = np.arange(100.0).reshape(10, 10) / 100
    write_quicklook(_store(red, red, red), tmp_path / "q.png")
    assert seen["titles"][0] == "true colour (B4 B3 B2)\nL2 reflectance, each channel stretched 2–98 %"


def test_the_hand_layout_keeps_every_text_inside_the_figure_and_the_panels_apart(tmp_path, monkeypatch) -> None:
    """The panels laid out without a layout engine, drawn: every title, tick label and colorbar label inside the
    figure, and each panel (its image, colorbar and their texts) left of the next one; the map on a long unit."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    seen = {}

    def capture(fig, path, **options):
        seen["fig"] = fig
        return path

    monkeypatch.setattr(image_quicklook, "save_png", capture)
    red = np.arange(400.0).reshape(20, 20) / 400
    store = _store(red, red, red)
    for name, units in (("analysis_map", "µg cm-2"), ("analysis_truth", "µg cm-2"), ("analysis_error", "µg cm-2")):
        store.create(name, ("y_20m", "x_20m"), np.float32, {"units": units})
        store.write(name, slice(0, 10), np.linspace(-40.0, 80.0, 100).reshape(10, 10).astype(np.float32))
    write_quicklook(store, tmp_path / "q.png", "analysis_map")
    fig = seen["fig"]
    renderer = FigureCanvasAgg(fig).get_renderer()
    fig.draw(renderer)
    width, height = fig.bbox.width, fig.bbox.height
    texts = [t for t in fig.findobj(lambda a: hasattr(a, "get_text") and a.get_text() and a.get_visible())]
    assert len(texts) > 20
    for t in texts:
        box = t.get_window_extent(renderer)
        assert box.x0 >= 0 and box.x1 <= width and box.y0 >= 0 and box.y1 <= height, (t.get_text(), box)
    images = [ax for ax in fig.axes if ax.images]  # the panels' image axes, left to right (colorbars draw no image)
    assert [ax.get_title() for ax in images] == [image_quicklook.TRUE_COLOUR_TITLE, "analysis map", "status",
                                                 "analysis error"]
    extents = []
    for i, ax in enumerate(images):
        after = images[i + 1].get_position().x0 if i + 1 < len(images) else 1.0
        own = [a for a in fig.axes if ax.get_position().x0 <= a.get_position().x0 < after]
        extents.append((min(a.get_tightbbox(renderer).x0 for a in own), max(a.get_tightbbox(renderer).x1 for a in own)))
    for (_, right), (left, _) in itertools.pairwise(extents):
        assert right < left
