"""bench.paper_runs, the regeneration of docs/paper.md's numbers: which runs it skips, resumes or
redoes, the B5/B6-apart search, and the Markdown it prints from docs/paper/results.json. No sweep
runs here (the subprocess is replaced); the full command takes about 13 minutes."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest


@pytest.fixture
def paper_runs(bench_path: None) -> ModuleType:
    from bench import paper_runs

    return paper_runs


@pytest.fixture
def fake_optimise(monkeypatch: pytest.MonkeyPatch) -> list[list[str]]:
    """Replace the ``s2cl optimise`` subprocess by one that records its command and succeeds."""
    calls: list[list[str]] = []

    def run(cmd: list[str], **kwargs: Any) -> subprocess.CompletedProcess:
        calls.append(cmd)
        return subprocess.CompletedProcess(cmd, 0)

    monkeypatch.setattr(subprocess, "run", run)
    return calls


def _marker_path(folder: Path) -> Path:
    """Where paper_runs keeps a run's marker: beside its log (s2cl writes only into its own folders)."""
    path = folder.parent / "logs" / f"{folder.name}.paper_runs.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _marker(folder: Path) -> dict[str, Any]:
    return json.loads(_marker_path(folder).read_text())


def test_finished_run_with_same_sources_is_skipped(paper_runs: ModuleType, fake_optimise: list, tmp_path: Path) -> None:
    folder = tmp_path / "table4-b4"
    folder.mkdir()
    fp = paper_runs.source_fingerprint("table4-b4")
    _marker_path(folder).write_text(json.dumps({"fingerprint": fp, "finished": True, "wall_s": 1.0}))
    assert paper_runs.run_scene("table4-b4", tmp_path)["wall_s"] == 1.0
    assert fake_optimise == []


def test_run_with_other_sources_is_redone_from_scratch(paper_runs: ModuleType, fake_optimise: list,
                                                       tmp_path: Path) -> None:
    folder = tmp_path / "table4-b4"
    folder.mkdir()
    (folder / "manifest.json").write_text("{}")
    (folder / "old-chunk").write_text("made by older code")
    _marker_path(folder).write_text(json.dumps({"fingerprint": "older", "finished": True}))
    paper_runs.run_scene("table4-b4", tmp_path)
    assert not (folder / "old-chunk").exists()  # the sweep's own resume would have kept it
    (cmd,) = fake_optimise
    assert cmd[1:] == ["-m", "s2cl", "optimise", "table4-b4", "-q", "-o", str(folder)]
    m = _marker(folder)
    assert m["finished"] and not m["resumed"] and m["fingerprint"] == paper_runs.source_fingerprint("table4-b4")


def test_interrupted_run_resumes_in_place(paper_runs: ModuleType, fake_optimise: list, tmp_path: Path) -> None:
    folder = tmp_path / "table4-b4"
    folder.mkdir()
    (folder / "chunk").write_text("finished chunk")
    fp = paper_runs.source_fingerprint("table4-b4")
    _marker_path(folder).write_text(json.dumps({"fingerprint": fp, "finished": False}))
    paper_runs.run_scene("table4-b4", tmp_path)
    assert (folder / "chunk").exists() and len(fake_optimise) == 1 and _marker(folder)["resumed"]


def test_foreign_folder_is_not_deleted(paper_runs: ModuleType, fake_optimise: list, tmp_path: Path) -> None:
    (tmp_path / "table4-b4").mkdir()
    (tmp_path / "table4-b4" / "notes.txt").write_text("mine")
    with pytest.raises(SystemExit, match="not an s2cl sweep folder"):
        paper_runs.run_scene("table4-b4", tmp_path)
    assert (tmp_path / "table4-b4" / "notes.txt").exists() and fake_optimise == []


def test_fingerprint_depends_on_the_scene(paper_runs: ModuleType) -> None:
    assert paper_runs.source_fingerprint("table4-b4") != paper_runs.source_fingerprint("table5-b11")


def test_best_apart(paper_runs: ModuleType) -> None:
    import pandas as pd

    df = pd.DataFrame({"B4_centre_nm": [675.0] * 3, "B4_width_nm": [30.0] * 3,
                       "B5_centre_nm": [720.0, 710.0, 710.0], "B5_width_nm": [40.0, 20.0, 20.0],
                       "B6_centre_nm": [735.0, 735.0, 730.0], "B6_width_nm": [30.0, 30.0, 20.0],
                       "rms": [4.0, 5.0, 4.5], "robust_rms": [4.0, 5.0, 4.5]})
    # 720/40 and 735/30 overlap (15 < 35); 710/20 and 735/30 are apart (25 >= 25), 710/20 730/20 too (20 >= 20)
    got = paper_runs.best_apart(df)
    assert got["configurations"] == 2 and got["rms"] == 4.5
    assert got["bands"] == {"B4": [675.0, 30.0], "B5": [710.0, 20.0], "B6": [730.0, 20.0]}
    assert paper_runs.best_apart(df.drop(columns=["B6_centre_nm", "B6_width_nm"])) is None


def test_tables_come_from_results_json(paper_runs: ModuleType, capsys: pytest.CaptureFixture[str]) -> None:
    data = json.loads(paper_runs.RESULTS_JSON.read_text())
    paper_runs.main(["--tables"])
    out = capsys.readouterr().out
    table3 = out.split("### Table 3")[1].split("###")[0]
    rows = [r for r in table3.splitlines() if r.startswith("| Lib")]
    assert len(rows) == 6
    for name, e in data["scenes"].items():
        if name.startswith("table3-"):
            assert f"| {e['best']['rms']:.2f} |" in table3 and f"| {e['ranked']:,} |" in table3
            assert e["underdetermined"]["count"] + e["ranked"] == e["configurations"]
    assert "### table6-b12 at FWHM 50" in out
