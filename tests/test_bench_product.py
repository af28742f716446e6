"""``python -m bench.bench_product`` on a tiny product, so that the throughput benchmark cannot rot: the product is
written in its layout, the end-to-end run happens in a child process under the --max-memory given, and (a) and (b)
read the same pixels. No timing is asserted. And the self-time accounting of its step timers, on a fake clock."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.bench
pytest.importorskip("rasterio", reason="the geo extra (rasterio, pyproj) reads GeoTIFF")


def test_a_tiny_product_runs_end_to_end_against_the_read_and_the_kernel(bench_path: None) -> None:
    from bench.bench_product import STEPS, bench

    r = bench(24, "1G", None, repeat=3)
    assert r["pixels"] == 24 * 24 and r["bands"] == 224
    for key in ("end_to_end_s", "read_alone_s", "kernel_alone_s"):  # the median of the three runs of each
        assert len(r["samples"][key]) == 3 and r[key] == sorted(r["samples"][key])[1]
    assert r["ratios"] == pytest.approx([e / (a + b) for e, a, b in zip(*r["samples"].values(), strict=True)])
    assert {"end_to_end", "read_alone", "kernel_alone"} <= set(r["pixels_per_s"])
    assert r["end_to_end_s"] > 0 and r["read_alone_s"] > 0 and r["kernel_alone_s"] > 0
    assert r["ratio_to_read_plus_kernel"] == pytest.approx(r["end_to_end_s"] / (r["read_alone_s"]
                                                                                 + r["kernel_alone_s"]))
    names = {name for _, _, name in STEPS}
    assert set(r["steps_s"]) == names  # every step of the chain ran, and was timed
    assert r["step_calls"]["retrieval map (IGRM)"] >= 2  # retrieved by row blocks as they are written, then written
    assert r["max_rss_bytes"] > 0 and r["written"] == ["simulation.nc", "simulation.json", "quicklook.png"]


def test_step_timers_count_self_time(monkeypatch) -> None:
    """outer calls inner twice; each call's time is the clock's reads around it, inner's subtracted from outer's."""
    from bench import bench_product

    clock = iter(range(0, 1000))
    monkeypatch.setattr(bench_product.time, "perf_counter", lambda: float(next(clock)))

    class Owner:
        @staticmethod
        def inner() -> None:
            for _ in range(1):
                next(clock)  # one tick inside, plus the two the timer reads

        @staticmethod
        def outer() -> None:
            Owner.inner()
            Owner.inner()
            next(clock)

    timers = bench_product.StepTimers()
    timers.wrap(Owner, "inner", "inner")
    timers.wrap(Owner, "outer", "outer")
    Owner.outer()
    # clock reads: outer start 0; inner start 1, tick 2, end 3 (2 s); inner start 4, tick 5, end 6 (2 s); tick 7;
    # outer end 8 (8 s, of which 4 in inner)
    assert timers.seconds == {"inner": 4.0, "outer": 4.0}
    assert timers.calls == {"inner": 2, "outer": 1}
