"""The Python API does the main job: ``s2cl.optimise`` returns what ``s2cl optimise`` prints, as data."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

import s2cl


@pytest.mark.slow
def test_optimise_returns_the_ranking_the_cli_prints(tmp_path) -> None:
    """The built-in default scene through the CLI and through ``s2cl.optimise``: the same best designs in the same
    order, the same reference row, the same summary; the ranking as a DataFrame, every configuration on request."""
    cli = subprocess.run([sys.executable, "-m", "s2cl", "optimise", "default", "-o", str(tmp_path / "cli")],
                         capture_output=True, text=True, timeout=600)
    assert cli.returncode == 0, cli.stderr
    result = s2cl.optimise("default", tmp_path / "api")
    printed = json.loads((tmp_path / "cli" / "summary.json").read_text(encoding="utf-8"))
    assert [e["bands"] for e in result.summary["top"]] == [e["bands"] for e in printed["top"]]
    assert result.reference["rms"] == printed["reference"]["rms"]
    ranking = result.ranking
    assert list(ranking["rank"]) == list(range(1, len(printed["top"]) + 1))
    assert ranking.loc[0, "rms"] == printed["top"][0]["rms"] == result.best["rms"]
    best = printed["top"][0]["bands"]
    row = "#1 " + " ".join(f"{c:g}/{w:g}" for c, w in best.values())
    assert any(" ".join(line.replace("│", " ").split()).startswith(row) for line in cli.stdout.splitlines()), cli.stdout
    for band, (centre, width) in best.items():
        assert (ranking.loc[0, f"{band}_centre_nm"], ranking.loc[0, f"{band}_width_nm"]) == (centre, width)
    assert len(result.table()) == printed["configurations"] == printed["ranked"] + printed["underdetermined"]["count"]
    assert result.written[0].name == "results.parquet" and all(p.exists() for p in result.written)


def test_optimise_refuses_before_creating_anything(tmp_path) -> None:
    with pytest.raises(s2cl.InputError, match="workers or a scheduler"):
        s2cl.optimise("default", tmp_path / "out", workers=2, scheduler="tcp://127.0.0.1:1")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("options", "said"), [({"chunk": 0}, "--chunk: must be at least 1"),
                                               ({"workers": 0}, "--workers: must be 1 to 1024"),
                                               ({"scheduler": "tcp://host"}, "--scheduler: ")])
def test_the_api_checks_what_the_command_line_checks(tmp_path, options: dict, said: str) -> None:
    with pytest.raises(s2cl.InputError, match=said):
        s2cl.optimise("default", tmp_path / "out", **options)
    assert not (tmp_path / "out").exists()
