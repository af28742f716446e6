"""docs/mission.md, the worked example of issue 35 (``scenes/mission-s2.toml``): its files and its generated blocks.

    python -m s2cl optimise mission-s2 -o OUT          # the exhaustive sweep (results.parquet stays in OUT)
    python -m bench.mission_report OUT                 # docs/mission/: summary.json, pareto.png, front.csv
    python -m s2cl scorecard mission-s2 -s sentinel2 -s S2A -s S2B -s OLI -s landsat-next \\
        -s results:docs/mission:balanced -o docs/mission/scorecard
    python -m bench.doc_blocks                        # the tables of docs/mission.md from those files

The blocks read only the committed files under docs/mission/ and the scene file: ``summary.json`` (the run, its
applications and ``pareto`` record), ``front.csv`` (every design of the Pareto front, its bands and each
application's score, taken from the run's results.parquet by this module) and ``scorecard/scorecard.json``.
"""

from __future__ import annotations

import argparse
import csv
import json
import shutil
import sys
import tomllib
from functools import cache
from pathlib import Path
from typing import Any

from bench.common import ROOT
from bench.doc_scorecard import scorecard_markdown

MISSION = ROOT / "docs" / "mission"
SCENE = ROOT / "scenes" / "mission-s2.toml"
SCORECARD_COMMAND = ("s2cl scorecard mission-s2 -s sentinel2 -s S2A -s S2B -s OLI -s landsat-next "
                     "-s results:docs/mission:balanced -o docs/mission/scorecard")


# -- the files ------------------------------------------------------------------------------------------------------

def write_files(results: Path, out: Path = MISSION) -> list[Path]:
    """Copy ``results``' summary.json and pareto.png into ``out`` and write ``out/front.csv``: the rows of
    results.parquet marked ``pareto``, with ``config``, each swept band's centre and width and each application's
    score column (the full file stays where the sweep wrote it)."""
    import pandas as pd

    summary = json.loads((results / "summary.json").read_text(encoding="utf-8"))
    columns = [a["column"] for a in summary["applications"]]
    bands = [f"{b}_{k}_nm" for b in summary["bands"] for k in ("centre", "width")]
    table = pd.read_parquet(results / "results.parquet", columns=["config", *bands, *columns, "pareto"])
    front = table[table["pareto"]].drop(columns="pareto").sort_values("config")
    out.mkdir(parents=True, exist_ok=True)
    written = [out / "summary.json", out / "pareto.png", out / "front.csv"]
    shutil.copyfile(results / "summary.json", written[0])
    shutil.copyfile(results / "pareto.png", written[1])
    front.to_csv(written[2], index=False, float_format="%.10g")
    return written


@cache
def _summary() -> dict[str, Any]:
    return json.loads((MISSION / "summary.json").read_text(encoding="utf-8"))


@cache
def _scene() -> dict[str, Any]:
    return tomllib.loads(SCENE.read_text(encoding="utf-8"))


def _front() -> list[dict[str, float]]:
    with (MISSION / "front.csv").open(encoding="utf-8") as f:
        return [{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)]


def _rel(path: Path) -> str:
    return path.relative_to(ROOT).as_posix()


def _design(bands: dict[str, Any]) -> list[str]:
    return [f"{c:g}/{w:g}" for c, w in bands.values()]


# -- the blocks ------------------------------------------------------------------------------------------------------

def _variants() -> dict[str, list[tuple[float, float]]]:
    """Each swept band's (centre, width) variants, nm, as the scene file defines them (:func:`s2cl.sweep.space`)."""
    from s2cl.scene.scene import Scene
    from s2cl.sweep.space import sweep_space

    scene = Scene.load(SCENE)
    space = sweep_space(scene.spec.sweep, scene.sensor, scene.grid, 0.0)
    return {r.band: [(float(c), float(w)) for c, w in r.variants()] for r in space.ranges}


def space_block() -> str:
    """The swept bands (variants, who reads them) and the applications (library, retrieval, bands read, designs
    scored, own-bands score, requirement, noise margin), then the run."""
    from bench.doc_tables import md_table

    s, scene = _summary(), _scene()
    p = s["pareto"]
    variants = _variants()
    readers = {b: [a["name"] for a in s["applications"] if b in a["bands"]] for b in variants}
    band_rows = [[b, len(v), f"{min(c for c, _ in v):g}–{max(c for c, _ in v):g}",
                  f"{min(w for _, w in v):g}–{max(w for _, w in v):g}", ", ".join(readers[b])]
                 for b, v in variants.items()]
    libraries = {a["name"]: a.get("library", scene["surface"]["library"]) for a in scene["application"]}
    rows, scored = [], 0
    for a in s["applications"]:
        what = f"{a['kind']} → {a['parameter']}" if a.get("parameter") else a["kind"]
        own = 1
        for b in a["bands"]:
            own *= len(variants.get(b, [None]))
        scored += own
        rows.append([a["name"], f"`{libraries[a['name']]}`", what, " ".join(a["bands"]), f"{own:,}",
                     f"`{a['column']}`", a["units"], f"{a['reference']:.4g}", f"{a['target']:g}",
                     f"{p['margins'][a['name']]['margin']:.3g}"])
    und = s["underdetermined"]["count"]
    return (md_table(["band", "variants", "centres nm", "widths nm", "read by"], band_rows) + "\n\n"
            + md_table(["application", "library", "retrieval", "bands read", "designs scored", "column", "units",
                        "Sentinel-2's own bands", "target", "noise margin"], rows)
            + f"\n\n{s['configurations']:,} joint designs (the product of the bands' variants) from {scored:,} "
            f"designs scored by the applications; {und:,} joint designs are underdetermined for "
            f"{s['applications'][0]['name']} (left out), {p['designs']:,} ranked. The sweep took "
            f"{s['seconds']:.1f} s (`summary.json` → `seconds`; 2 CPU cores). From `{_rel(MISSION / 'summary.json')}` "
            "(written by `s2cl optimise mission-s2 -o OUT`, copied by `python -m bench.mission_report OUT`) and the "
            "scene file (the variants).")


def _best_on_front(front: list[dict[str, float]], column: str, columns: list[str],
                   refs: list[float]) -> dict[str, float]:
    """The front design best on ``column``; ties by relative sum, then configuration number."""
    def rel(r: dict[str, float]) -> float:
        return sum(r[c] / ref for c, ref in zip(columns, refs, strict=True))
    return min(front, key=lambda r: (r[column], rel(r), r["config"]))


def front_block() -> str:
    """The designs that matter: Sentinel-2's own bands, the balanced design, each application's best on the front;
    then the positions the front takes per band, and the designs meeting every requirement."""
    from bench.doc_tables import md_table

    s = _summary()
    p, apps, bands = s["pareto"], s["applications"], s["bands"]
    columns, refs = [a["column"] for a in apps], [a["reference"] for a in apps]
    front = _front()
    own = {b: s["reference"]["bands"][b] for b in bands} if isinstance(s["reference"].get("bands"), dict) else None

    def scores(values: list[float]) -> list[str]:
        return [f"{v:.4g} ({v / r:.3f})" for v, r in zip(values, refs, strict=True)]

    def rel(values: list[float]) -> str:
        return f"{sum(v / r for v, r in zip(values, refs, strict=True)):.3f}"

    rows = []
    if own is not None:
        rows.append(["Sentinel-2's own bands", *_design(own), *scores(refs), rel(refs)])
    balanced = p["front"]["designs"][0]
    bal = [balanced["scores"][a["name"]] for a in apps]
    rows.append([f"balanced (best by relative sum), config {balanced['config']}", *_design(balanced["bands"]),
                 *scores(bal), rel(bal)])
    for a in apps:
        r = _best_on_front(front, a["column"], columns, refs)
        values = [r[c] for c in columns]
        rows.append([f"best for {a['name']}, config {int(r['config'])}",
                     *[f"{r[f'{b}_centre_nm']:g}/{r[f'{b}_width_nm']:g}" for b in bands], *scores(values),
                     rel(values)])
    table = md_table(["design", *[f"{b} nm" for b in bands], *[a["name"] for a in apps], "relative sum"], rows)
    spread = []
    for b in bands:
        shapes = sorted({(r[f"{b}_centre_nm"], r[f"{b}_width_nm"]) for r in front})
        centres = sorted({c for c, _ in shapes})
        spread.append([b, len(shapes), ", ".join(f"{c:g}" for c in centres),
                       ", ".join(f"{w:g}" for w in sorted({w for _, w in shapes}))])
    m = p["meeting"]
    targets = ", ".join(f"{n} ≤ {t:g}" for n, t in m["targets"].items())
    return (f"The front: **{p['front']['count']} of {p['designs']:,} designs**; **{m['count']:,} designs** meet "
            f"every requirement ({targets}).\n\n" + table
            + "\n\nEach score: the application's metric (units above) and, in brackets, over Sentinel-2's own "
            "bands' score (below 1: better). \"Best for\" an application: the front design with its lowest score "
            "(ties: the lower relative sum). The positions the front takes:\n\n"
            + md_table(["band", "shapes on the front", "centres nm", "widths nm"], spread)
            + f"\n\nFrom `{_rel(MISSION / 'summary.json')}` (`pareto`) and `{_rel(MISSION / 'front.csv')}` (the "
            "front's rows of the run's results.parquet; written by `python -m bench.mission_report OUT`).")


def scorecard_block() -> str:
    """The scorecard of the scene over Sentinel-2 (model and measured SRFs), OLI, Landsat Next and the balanced
    design."""
    path = MISSION / "scorecard" / "scorecard.json"
    return scorecard_markdown(path, f"Written by `{SCORECARD_COMMAND}` into `{_rel(path)}` (the heatmap beside it: "
                                    "`scorecard.png`).")


BLOCKS = {"mission.space": space_block, "mission.front": front_block, "mission.scorecard": scorecard_block}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench.mission_report", description=__doc__.splitlines()[0])
    parser.add_argument("results", type=Path, help="the output folder of `s2cl optimise mission-s2 -o OUT`")
    args = parser.parse_args(argv)
    for path in write_files(args.results):
        print(f"wrote {_rel(path)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
