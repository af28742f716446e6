"""The search of a scene with several applications (issue 35, item 4): on a space small enough to sweep, the designs
the search scores on every pixel carry the exhaustive run's scores bit for bit and its Pareto front is the
exhaustive front, found here by a plain pairwise dominance test; a killed search resumes to the same bytes; a
joint space above ``search_start`` is refused in one line; a rung keeps whole non-dominated layers."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_multi_application import TWO

import s2cl
from s2cl.errors import InputError
from s2cl.sweep.front_search import layers_kept

COLUMNS = ["chlorophyll_rms", "leaf_water_rms"]
SEARCH = TWO.replace("within_noise_top = 0", 'within_noise_top = 0\nsearch = "halving"\nsearch_finalists = 2\n'
                     "search_keep = 0.5\nsearch_start = 100")


def _write(tmp_path, name: str, text: str):  # type: ignore[no-untyped-def]
    path = tmp_path / f"{name}.toml"
    path.write_text(text, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):  # type: ignore[no-untyped-def]
    """The exhaustive two-application sweep (48 joint designs) and its search, run once for the module."""
    tmp = tmp_path_factory.mktemp("front_search")
    ex = s2cl.optimise(_write(tmp, "ex", TWO), tmp / "ex")
    se = s2cl.optimise(_write(tmp, "se", SEARCH), tmp / "se")
    return tmp, ex, se


def _front(rows: list[tuple[int, list[float]]], margins: list[float]) -> set[int]:
    """The designs no other dominates (docs/pareto.md's rule, written pairwise)."""
    def dominates(a: list[float], b: list[float]) -> bool:
        return all(x <= y for x, y in zip(a, b, strict=True)) and any(
            y - x > m for x, y, m in zip(a, b, margins, strict=True))
    return {c for c, s in rows if not any(dominates(t, s) for _, t in rows)}


def _rows(df: pd.DataFrame) -> list[tuple[int, list[float]]]:
    out = [(int(c), [float(v) for v in vals]) for c, *vals in df[["config", *COLUMNS]].itertuples(index=False)]
    return [(c, s) for c, s in out if all(np.isfinite(s))]


def test_full_fidelity_scores_are_the_exhaustive_run_s_bit_for_bit(runs) -> None:  # type: ignore[no-untyped-def]
    tmp, _, _ = runs
    a = pd.read_parquet(tmp / "ex" / "results.parquet").set_index("config")
    b = pd.read_parquet(tmp / "se" / "results.parquet")
    full = b[b["full_fidelity"]]
    assert 0 < len(full) < len(a)
    for c in [*COLUMNS, "rms", "underdetermined"]:
        assert a.loc[full["config"], c].to_numpy().tobytes() == full[c].to_numpy().tobytes(), c
    assert (b.loc[~b["full_fidelity"], "copies"] < 3).all()  # the others stopped on fewer copies
    assert set(b["config"]) == set(range(48))  # every joint design started on one copy


def test_the_searched_front_is_the_exhaustive_front(runs) -> None:  # type: ignore[no-untyped-def]
    """With the exhaustive run's margins, and with none (strict dominance), the front of the designs the search
    scored on every pixel is the exhaustive front; the search's own summary front and margins too."""
    tmp, ex, se = runs
    a = _rows(pd.read_parquet(tmp / "ex" / "results.parquet"))
    b = pd.read_parquet(tmp / "se" / "results.parquet")
    full = _rows(b[b["full_fidelity"]])
    margins = [ex.summary["pareto"]["margins"][n]["margin"] for n in ("chlorophyll", "leaf_water")]
    for m in (margins, [0.0, 0.0]):
        assert _front(full, m) == _front(a, m)
    assert set(se.summary["pareto"]["front"]["configs"]) == set(ex.summary["pareto"]["front"]["configs"])
    record = se.summary["search"]
    assert record["exhaustive_pixel_evaluations"] == sum(
        n * p for n, p in zip(record["exhaustive_application_configurations"], (120 * 2, 246 * 3), strict=True))
    assert [len(s["rungs"]) for s in record["stages"]][::3] == [3, 3]  # pass 1, each application's own best, pass 2
    for n in ("chlorophyll", "leaf_water"):  # measured on each application's own best designs, as exhaustively
        assert se.summary["pareto"]["margins"][n]["margin"] == ex.summary["pareto"]["margins"][n]["margin"]


def test_a_killed_search_resumes_to_the_same_bytes(runs, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Stopped after its third batch, the search started again computes only the rest and writes the same file."""
    tmp, _, _ = runs
    import s2cl.sweep.search as search

    scene = _write(tmp, "killed", SEARCH)
    real, calls = search.Scorer._store, []

    def store(self, start, rows, copies):  # type: ignore[no-untyped-def]
        if len(calls) == 3:
            raise KeyboardInterrupt
        calls.append(start)
        real(self, start, rows, copies)

    monkeypatch.setattr(search.Scorer, "_store", store)
    with pytest.raises(KeyboardInterrupt):
        s2cl.optimise(scene, tmp / "killed")
    computed: list[int] = []

    def counted(self, start, rows, copies):  # type: ignore[no-untyped-def]
        computed.append(start)
        real(self, start, rows, copies)

    monkeypatch.setattr(search.Scorer, "_store", counted)
    s2cl.optimise(scene, tmp / "killed")
    assert (tmp / "killed" / "results.parquet").read_bytes() == (tmp / "se" / "results.parquet").read_bytes()
    resumed = len(computed)
    computed.clear()
    s2cl.optimise(_write(tmp, "fresh", SEARCH), tmp / "fresh")
    assert resumed == len(computed) - 3  # the three batches on disk were read, not computed


def test_a_joint_space_above_search_start_is_one_line(tmp_path) -> None:  # type: ignore[no-untyped-def]
    scene = _write(tmp_path, "big", SEARCH.replace("search_start = 100", "search_start = 100\n")
                   .replace('B11 = { centres = [1600, 1640], widths = [50, 100] }',
                            'B11 = { centres = [1600, 1610, 1620, 1630, 1640], widths = [50, 100] }'))
    with pytest.raises(InputError) as e:
        s2cl.optimise(scene, tmp_path / "big")
    text = str(e.value)
    assert text.startswith(f"{scene}: sweep.search_start: ") and "\n" not in text and "has 120" in text
    assert not (tmp_path / "big").exists()


def test_a_rung_keeps_whole_non_dominated_layers() -> None:
    """Layers by hand: (1, 5), (5, 1) and (2, 2) are the first; (3, 3) the second; (4, 6) the third; an unscored
    design only when every scored one is kept."""
    s = np.array([[1, 5], [5, 1], [3, 3], [2, 2], [4, 6], [np.inf, 0]], dtype=float)
    assert layers_kept(s, 1).tolist() == [True, True, False, True, False, False]
    assert layers_kept(s, 4).tolist() == [True, True, True, True, False, False]
    assert layers_kept(s, 6).tolist() == [True] * 6
    # within margins of 1.5, (3, 3) is not dominated by (2, 2): one layer
    assert layers_kept(s, 1, np.array([1.5, 1.5])).tolist() == [True, True, True, True, False, False]
