"""bench.soil_backgrounds: the objective soil selection and the summary it reports (the sweep itself is the
bench's run; its numbers are in bench/results/soil_backgrounds.json)."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.grid import SpectralGrid
from s2cl.libraries import earthlib_spectra as el


@pytest.fixture
def bench_module(bench_path):
    from bench import soil_backgrounds

    return soil_backgrounds


def test_selection_follows_the_indices_one_soil_per_site(bench_module):
    sets = bench_module.select_soils(5)
    assert list(sets) == ["usgs-stand-ins", "fe-depth-top", "redness-top", "fe-depth-bottom"]
    lib = el.soil_library(SpectralGrid(400.0, 1000.0, 10.0))
    depth, site = lib.params["fe_band_depth"], lib.params["site"]
    top, bottom = sets["fe-depth-top"], sets["fe-depth-bottom"]
    assert top["fe_band_depth"][0] == pytest.approx(depth.max(), abs=1e-4)
    assert bottom["fe_band_depth"][0] == pytest.approx(depth.min(), abs=1e-4)
    assert min(top["fe_band_depth"]) > np.quantile(depth, 0.99) > max(bottom["fe_band_depth"])
    for entry in (top, sets["redness-top"], bottom):
        assert len(entry["backgrounds"]) == 5 and all(b.startswith("earthlib:") for b in entry["backgrounds"])
        known = [s for s in entry["site"] if s != 0]
        assert len(set(known)) == len(known)
        names = [b.split(":", 1)[1] for b in entry["backgrounds"]]
        assert [int(site[lib.names.index(n)]) for n in names] == entry["site"]


def test_centre_means_reads_the_b4_grid(bench_module):
    centres = [660.0, 665.0, 670.0, 675.0, 680.0]
    widths = [15.0, 30.0]
    rms = [[10.0, 20.0], [8.0, 12.0], [1.0, 1.0], [4.0, 4.0], [2.0, 6.0]]
    got = bench_module.centre_means({"centres_nm": centres, "widths_nm": widths, "rms": rms})
    assert got["660/30"] == 20.0 and got["660/all"] == 15.0 and got["680/30"] == 6.0
    assert got["ratio_660_665_to_675_680"] == pytest.approx((20.0 + 12.0) / (4.0 + 6.0))
