"""The results writers behind docs/atmos.md's generated blocks (bench/lut_accuracy.py, bench/correction_residuals.py)
on tiny slices: the numbers they write are what they claim to be. No timing is asserted."""

from __future__ import annotations

import pytest
from sixs_marks import sixs_test

pytestmark = pytest.mark.bench


@pytest.fixture
def lut():
    from s2cl.atmos.atmosphere import AtmosphereLUT

    return AtmosphereLUT.load()


def test_on_nodes_tells_node_states_from_off_node_ones(bench_path: None, lut) -> None:
    from bench import lut_accuracy as la

    assert all(la.on_nodes(lut, s) for s in la.NODE_STATES.values())
    off = [s for g, states in la.OFF_NODE.items() if not g.startswith("ozone") for _, s in states]
    assert off and not any(la.on_nodes(lut, s) for s in off)
    assert all(la.on_nodes(lut, s) for _, s in la.OFF_NODE["ozone (DU)"])  # ozone has no nodes (Beer's law)


def test_correction_residuals_of_flat_targets_are_tiny_and_of_minerals_are_not(bench_path: None) -> None:
    from bench import correction_residuals as cr

    r = cr.measure(("builtin:flat", "builtin:minerals"))
    flat, minerals = r["libraries"]["builtin:flat"], r["libraries"]["builtin:minerals"]
    assert len(flat["max_abs"]) == len(r["bands"]) == 13 and flat["spectra"] == 2
    assert max(flat["max_abs"]) < 1e-5
    assert max(minerals["max_abs"]) > 1e-3  # structure inside B10 and B12


@sixs_test
def test_formula_errors_at_a_node_and_between_nodes(bench_path: None, lut, monkeypatch) -> None:
    from bench import lut_accuracy as la

    monkeypatch.setattr(la, "PAPER_WAVELENGTHS_NM", (550.0, 1610.0))
    monkeypatch.setattr(la, "PAPER_REFLECTANCES", (0.3,))
    r = la.formula_errors(lut, {"node": la.STANDARD, "off": la.STANDARD.replace(aot550=0.7)}, workers=1)
    assert r["node"]["on_nodes"] and not r["off"]["on_nodes"]
    assert r["node"]["linear"]["max_abs"] < 3e-4  # the formula reproduces 6S to its print rounding
    assert len(r["node"]["linear"]["relative_error"]) == 2 and len(r["node"]["linear"]["relative_error"][0]) == 1
    # between nodes the interpolation error is added, and the nearest node is far worse than linear
    assert r["off"]["linear"]["max_abs"] > r["node"]["linear"]["max_abs"]
    assert r["off"]["nearest"]["max_abs"] > 5 * r["off"]["linear"]["max_abs"]


@sixs_test
def test_visibility_table_agrees_with_6s(bench_path: None, monkeypatch) -> None:
    from bench import lut_accuracy as la

    monkeypatch.setattr(la, "VISIBILITIES_KM", (8.0, 23.0))
    r = la.visibility(workers=1)
    assert r["max_abs_difference"] <= 5e-5 and r["s2cl_aot550"][1] == pytest.approx(0.23472, abs=1e-9)
