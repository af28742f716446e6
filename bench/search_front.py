"""The multi-application search against the exhaustive front (issue 35, item 4).

A two-application space small enough to sweep (:data:`SCENE`: chlorophyll by IGRM on Lib1 over B5, B6 and B7;
leaf water by GVMI on the leaf-water library with B7 as its NIR band and B11; B7 shared; 100 noise copies each)
runs twice through :func:`s2cl.optimise`: exhaustively and with ``search = "halving"`` (the other search keys at
their defaults). Reported: which designs of the exhaustive Pareto front the search scored on every pixel and put
on its front, with the same noise margins (the exhaustive run's) and with none (strict dominance); whether every
design of the searched front is on the exhaustive one; the share of the exhaustive sweep's pixel-evaluations
(each application's own sub-space on every pixel) the search used; and a check that every design the search scored
on every pixel carries exactly the exhaustive run's scores. Nothing asserts a timing.

    python -m bench.search_front       # bench/results/search-front.json (a few minutes), then
    python -m bench.doc_blocks         # its block of docs/applications.md
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path
from typing import Any

from bench.common import RESULTS, check, machine_info

OUT = RESULTS / "search-front.json"
COLUMNS = ["chlorophyll_rms", "leaf_water_rms"]
SCENE = """
[scene]
name = "search-front"
[surface]
library = "builtin:lib1"
quantity = "reflectance"
copies = 100
[effects]
atmosphere = true
correct = true
seed = 3
[[application]]
name = "chlorophyll"
[application.analysis]
kind = "igrm"
parameter = "cab"
bands = ["B4", "B5", "B6", "B7"]
[[application]]
name = "leaf_water"
library = "builtin:leaf-water"
analysis = { kind = "gvmi", parameter = "ewt", nir = "B7", swir = "B11" }
[sweep]
bands = ["B5", "B6", "B7", "B11"]
within_noise_top = 0
[sweep.ranges]
B5 = { centres = [695, 700, 705, 710], widths = [10, 20] }
B6 = { centres = [735, 740, 745], widths = [10, 20] }
B7 = { centres = [775, 790], widths = [15, 25] }
B11 = { centres = [1580, 1600, 1620, 1640, 1660, 1680], widths = [50, 100] }
"""


def measure() -> dict[str, Any]:
    """Run both, compare, return the record."""
    import numpy as np
    import pandas as pd

    import s2cl
    from s2cl.sweep.pareto import front

    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        (root / "exhaustive.toml").write_text(SCENE, encoding="utf-8")
        (root / "search.toml").write_text(SCENE.replace("within_noise_top = 0",
                                                        'within_noise_top = 0\nsearch = "halving"'), encoding="utf-8")
        t0 = time.perf_counter()
        ex = s2cl.optimise(root / "exhaustive.toml", root / "exhaustive")
        t1 = time.perf_counter()
        se = s2cl.optimise(root / "search.toml", root / "search")
        t2 = time.perf_counter()
        a = pd.read_parquet(root / "exhaustive" / "results.parquet")
        b = pd.read_parquet(root / "search" / "results.parquet")
    full = b[b["full_fidelity"].to_numpy(dtype=bool)]
    same = a.set_index("config").loc[full["config"], COLUMNS].to_numpy()
    check(same.tobytes() == full[COLUMNS].to_numpy().tobytes(),
          "every design the search scored on every pixel carries the exhaustive run's scores bit for bit")
    scored = a[np.isfinite(a[COLUMNS].to_numpy()).all(axis=1)]
    full = full[np.isfinite(full[COLUMNS].to_numpy()).all(axis=1)]
    margins = [ex.summary["pareto"]["margins"][n]["margin"] for n in ("chlorophyll", "leaf_water")]
    fronts = {}
    for name, m in (("margins", margins), ("strict", [0.0, 0.0])):
        fe = set(scored["config"][front(scored[COLUMNS].to_numpy(), m)].tolist())
        fs = set(full["config"][front(full[COLUMNS].to_numpy(), m)].tolist())
        fronts[name] = {"margins": m, "exhaustive_front": len(fe), "found": len(fe & fs),
                        "missed": sorted(fe - fs), "searched_front": len(fs),
                        "searched_not_exhaustive": sorted(fs - fe)}
    own = set(se.summary["pareto"]["front"]["configs"])
    ex_front = set(ex.summary["pareto"]["front"]["configs"])
    record = se.summary["search"]
    return {"machine": machine_info(), "scene": SCENE.strip(), "joint_designs": len(a),
            "application_designs": record["exhaustive_application_configurations"],
            "search": {k: record[k] for k in ("keep", "finalists", "evaluations", "pixel_evaluations",
                                              "exhaustive_pixel_evaluations", "pixel_evaluation_fraction",
                                              "full_fidelity_designs", "stages")},
            "fronts": fronts,
            "summaries": {"exhaustive_front": len(ex_front), "search_front": len(own),
                          "search_front_on_exhaustive": len(own & ex_front),
                          "search_margins": [se.summary["pareto"]["margins"][n]["margin"]
                                             for n in ("chlorophyll", "leaf_water")]},
            "seconds": {"exhaustive": t1 - t0, "search": t2 - t1}}


def block() -> str:
    """docs/applications.md's table of :data:`OUT`."""
    r = json.loads(OUT.read_text(encoding="utf-8"))
    s, f, m = r["search"], r["fronts"], r["summaries"]
    total = s["exhaustive_pixel_evaluations"]
    parts = []
    for st in s["stages"]:
        used = [g["pixel_evaluations"] for g in st["rungs"] if "pixel_evaluations" in g]
        share = f" ({100 * sum(used) / total:.1f} % of the exhaustive pixel-evaluations)" if used else ""
        parts.append(f"{st['stage']}: " + ", ".join(f"{g['designs']:,} on {g['copies']}" for g in st["rungs"]) + share)
    rungs = "; ".join(parts)
    lines = [f"Measured by `python -m bench.search_front` ({r['joint_designs']:,} joint designs; the applications' "
             f"own sub-spaces {' and '.join(f'{n:,}' for n in r['application_designs'])} designs; 100 noise copies; "
             f"search_keep {s['keep']}, search_finalists {s['finalists']}):", "",
             "| front rule | exhaustive front | found by the search | searched front | searched, not on the "
             "exhaustive front |", "|---|---:|---:|---:|---:|"]
    for name, words in (("margins", "noise margins (the exhaustive run's)"), ("strict", "strict (margins 0)")):
        x = f[name]
        lines.append(f"| {words} | {x['exhaustive_front']} | {x['found']} | {x['searched_front']} | "
                     f"{len(x['searched_not_exhaustive'])} |")
    lines += ["", f"Designs per rung (designs on copies), stage by stage: {rungs}; {s['full_fidelity_designs']} "
              f"scored on every pixel. Pixel-evaluations: {s['pixel_evaluations']:,} of the exhaustive sweep's "
              f"{s['exhaustive_pixel_evaluations']:,} ({100 * s['pixel_evaluation_fraction']:.1f} %). Every design "
              "scored on every pixel carries the exhaustive run's scores bit for bit (checked before writing).", "",
              f"The search's own `summary.json` front holds {m['search_front']} designs, "
              f"{m['search_front_on_exhaustive']} of them on the exhaustive run's {m['exhaustive_front']}: its noise "
              "margins are measured on the designs it scored on every pixel (each application's best of those), "
              f"{' and '.join(f'{x:.3g}' for x in m['search_margins'])} against the exhaustive run's "
              f"{' and '.join(f'{x:.3g}' for x in f['margins']['margins'])} (µg/cm², µm)."]
    return "\n".join(lines) + "\n"


BLOCKS = {"search.front": block}


def main() -> int:
    record = measure()
    OUT.write_text(json.dumps(record, indent=1) + "\n", encoding="utf-8")
    print(block())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
