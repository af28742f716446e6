"""The LUT builder's own arithmetic and axis checks (no 6S needed)."""

from __future__ import annotations

import numpy as np
import pytest

from s2cl.atmos.lut_axes import LUTAxes
from s2cl.atmos.lut_build import _command_line, _to_1nm
from s2cl.atmos.lut_runs import SCATTERING_NODES_UM, SCATTERING_SAMPLES_UM, _log_interp_matrix
from s2cl.atmos.sixs import on_sixs_grid
from s2cl.errors import InputError


def test_default_axes_cover_the_brief():
    axes = LUTAxes()
    assert axes.sixs_wavelengths_um.size == 841 and axes.wavelengths_nm.size == 2101
    assert all(on_sixs_grid(w) for w in axes.sixs_wavelengths_um)
    assert axes.aot550[0] == 0 and axes.aot550[-1] >= 0.8
    assert {0.4, 1.0, 1.5, 3.0} <= set(axes.water_vapour)  # the B10 study's columns are nodes


@pytest.mark.parametrize(("kwargs", "key"), [
    ({"aot550": (0.1, 0.2)}, "axes.aot550"),
    ({"aot550": (0.0, 0.2, 0.1)}, "axes.aot550"),
    ({"solar_zenith": (0.0, 30.0)}, "axes.reference_zenith"),
    ({"solar_zenith": (0.0, 40.0, 85.0)}, "axes.solar_zenith"),
    ({"wavelength_range_nm": (401.0, 2500.0)}, "axes.wavelength_range_nm"),
    ({"wavelength_range_nm": (400.0, 2600.0)}, "axes.wavelength_range_nm"),
    ({"ozone_range": (340.0, 500.0)}, "axes.ozone_range"),
    ({"profiles": ("tropical",)}, "profile"),
])  # fmt: skip
def test_bad_axes_name_the_key(kwargs, key):
    with pytest.raises(InputError) as info:
        LUTAxes(**kwargs)
    assert info.value.key == key


def test_samples_sit_one_per_interval_between_6s_fixed_wavelengths():
    nodes = np.asarray(SCATTERING_NODES_UM)
    inner = np.asarray(SCATTERING_SAMPLES_UM[1:])
    interval = np.searchsorted(nodes, inner) - 1
    assert SCATTERING_SAMPLES_UM[0] == nodes[0]
    assert list(interval) == list(range(nodes.size - 1))
    assert all(on_sixs_grid(w) for w in SCATTERING_SAMPLES_UM)


def test_power_law_matrix_reproduces_6s_interpolation():
    """6S: v(wl) = v_k (wl / wl_k) ** alpha_k with alpha_k from the neighbouring nodes."""
    rng = np.random.default_rng(3)
    node_values = rng.uniform(0.01, 1.0, len(SCATTERING_NODES_UM))
    wl = np.linspace(0.4, 3.75, 997)
    got = np.exp(_log_interp_matrix(wl) @ np.log(node_values))
    nodes = np.asarray(SCATTERING_NODES_UM)
    k = np.clip(np.searchsorted(nodes, wl) - 1, 0, nodes.size - 2)
    alpha = np.log(node_values[k + 1] / node_values[k]) / np.log(nodes[k + 1] / nodes[k])
    want = node_values[k] * (wl / nodes[k]) ** alpha
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_samples_determine_the_node_values():
    """19 samples, one per interval plus 0.4 um, pin down all 19 node values (what the builder solves)."""
    a = _log_interp_matrix(np.asarray(SCATTERING_SAMPLES_UM))
    assert np.linalg.matrix_rank(a) == len(SCATTERING_NODES_UM)
    assert np.linalg.cond(a) < 20  # rounding of 6S's printout is not amplified much
    truth = np.log(np.linspace(0.2, 0.01, len(SCATTERING_NODES_UM)))
    solved, *_ = np.linalg.lstsq(a, a @ truth, rcond=None)
    np.testing.assert_allclose(solved, truth, rtol=1e-12)


def test_to_1nm_keeps_6s_values_on_shared_wavelengths():
    wl6s = np.round(0.25 + 0.0025 * np.arange(60, 65), 6)  # 400-410 nm
    values = np.array([[1.0, 0.5, 0.8, 0.2, 0.9]])
    out = _to_1nm(values, wl6s, np.arange(400.0, 411.0))
    assert out[0, 0] == 1.0 and out[0, 5] == 0.8 and out[0, 10] == 0.9
    assert out[0, 1] == pytest.approx(1.0 - 0.4 * 0.5)


def test_command_line_has_no_machine_path(monkeypatch):
    monkeypatch.setattr("sys.argv", ["/some/where/bin/s2cl", "lut", "build", "-o", "out.npz"])
    assert _command_line() == "s2cl lut build -o out.npz"
    monkeypatch.setattr("sys.argv", ["/some/where/s2cl/__main__.py", "lut", "build", "-o", "out.npz"])
    assert _command_line() == "s2cl lut build -o out.npz"  # python -m s2cl


def test_lut_build_records_the_one_command_line(monkeypatch, tmp_path):
    """`s2cl lut build` records itself with the options given, however it was started; errors are one line."""
    from s2cl.cli import lut as lut_cli
    from s2cl.cli.main import main

    seen = {}

    def fake_build(output, axes, *, workers, progress, command):
        seen.update(axes=axes, workers=workers, progress=progress, command=command)
        raise InputError("stop here", source=str(output))

    monkeypatch.setattr("s2cl.atmos.lut_build.build_lut", fake_build)
    with pytest.raises(SystemExit) as info:
        main(["lut", "build", "-o", str(tmp_path / "x.npz"), "--aot", "0,0.2", "-q"])
    assert info.value.code == 2
    assert seen["command"] == f"s2cl lut build --output {tmp_path / 'x.npz'} --aot 0,0.2 --quiet"
    assert seen["axes"].aot550 == (0.0, 0.2) and seen["workers"] == 2 and seen["progress"] is False
    assert lut_cli.BUILD_COMMAND == "s2cl lut build"


def test_lut_build_refuses_bad_axes_in_one_line(capsys):
    from s2cl.cli.main import main

    with pytest.raises(SystemExit) as info:
        main(["lut", "build", "-o", "x.npz", "--aot", "0.1,0.2"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err == "error: axes.aot550: must start at 0 (the Rayleigh-only node), got 0.1\n"
