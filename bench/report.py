"""The suite's outputs from a results JSON, driven by :mod:`bench.registry` alone: a Markdown report
(a section per group, a table per family with the columns it declares, the columns' meanings), a
figure per group and, for a full run, docs/bench.md. Results of families the registry no longer
has are named in the report, not dropped silently."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bench import design_report, plots
from bench.common import ROOT, load_note
from bench.registry import FAMILIES, GROUPS, KEY_COLUMNS, Column, Family, Group, Result, Row, setting_cell
from s2cl.io.output import write_text

DOCS = ROOT / "docs"
Items = list[tuple[Family, Result]]


def table(columns: tuple[Column, ...], result: Result, rows: list[Row]) -> str:
    """A Markdown table of ``rows``; optional columns without a non-zero value are left out."""
    shown = [c for c in columns if not c.optional or any(c.value(r) for r in rows)]
    lines = ["| " + " | ".join(c.header(result) for c in shown) + " |", "|" + "---|" * len(shown)]
    lines += ["| " + " | ".join(c.text(r) for c in shown) + " |" for r in rows]
    return "\n".join(lines)


def family_md(f: Family, result: Result) -> str:
    """A family's caption and table (skipped rows as notes below it), or the error it failed with."""
    if "error" in result:
        return f"**{f.title}**: {'' if result.get('skipped') else 'failed: '}{result['error']}"
    rows = result.get(f.rows, [])
    kept = [r for r in rows if not r.get("skipped")]
    skipped = "".join(f"\n\n*{f.columns[0].value(r)}*" for r in rows if r.get("skipped"))
    return f"{f.table_caption(result)}\n\n{table(f.columns, result, kept)}{skipped}"


def group_items(results: Result, group: Group) -> tuple[Items, list[str]]:
    """The group's results in registry order, and the keys of results no family declares."""
    section = results.get(group.key, {})
    known = [(f, section[f.key]) for f in FAMILIES if f.group is group and f.key in section]
    return known, [k for k in section if k not in {f.key for f, _ in known}]


def key_table(group: Group, items: Items) -> str:
    """The reference's time, then per family its default and its ``key_settings`` rows."""
    assert group.key_table is not None
    rows: list[Row] = []
    ref = next((r for f, res in items if f.key_reference for r in res.get("rows", []) if r.get("reference")), None)
    if ref:
        rows.append({"knob": "reference", "setting": group.key_table.reference, "seconds": ref["seconds"],
                     "speedup": 1.0, "accuracy": "—"})
    for f, res in items:
        for r in res.get("rows", []):
            if r.get("skipped") or r.get("reference") or not (r.get("default") or r["setting"].startswith(
                    f.key_settings)):
                continue
            rows.append({"knob": f.title.split(":")[0], "setting": setting_cell(r), "seconds": r["seconds"],
                         "speedup": r.get("speedup"), "accuracy": f.accuracy(r) if f.accuracy else ""})
    return table(KEY_COLUMNS, {}, rows) + "\n\n" + group.key_table.note


def column_notes(items: Items) -> str:
    """What the columns of the group's tables mean (each column once)."""
    seen: dict[int, str] = {}
    for f, res in items:
        rows = res.get(f.rows, [])
        for c in f.columns:
            if c.doc and id(c) not in seen and (not c.optional or any(c.value(r) for r in rows)):
                seen[id(c)] = f"**{c.header(res)}**: {c.doc}"
    return "*Columns.* " + "; ".join(seen.values()) + "." if seen else ""


def group_figure(group: Group, items: Items, path: Path) -> Path | None:
    """The group's figure: an axis per family panel, one per shared panel."""
    if group.figure is None:
        return None
    panels: list[tuple[str, Any, list[tuple[str, Result]]]] = []
    shared: dict[Any, list[tuple[str, Result]]] = {}
    for f, res in items:
        if f.panel is None or "error" in res:
            continue
        if not f.panel.shared:
            panels.append((f.panel.title or f.title, f.panel.draw, [(f.title, res)]))
            continue
        if f.panel not in shared:
            shared[f.panel] = []
            panels.append((f.panel.title, f.panel.draw, shared[f.panel]))
        shared[f.panel].append((f.title, res))
    fig = group.figure
    return plots.figure(panels, path, size=fig.size, columns=fig.columns, suptitle=fig.suptitle)


def group_md(group: Group, results: Result, figure: str | None, *, docs: bool) -> str:
    """A group's section: intro, key table, figure, why the defaults (docs), the families' tables."""
    items, unknown = group_items(results, group)
    out = [f"## {group.heading}" + (f"\n\n{group.intro(results)}" if group.intro else "")]
    if group.key_table:
        out.append(key_table(group, items))
    if figure and group.figure:
        out.append(f"![{group.figure.alt}]({figure})")
    whys = [w for f, res in items if f.why and "error" not in res and (w := f.why(res))] if docs else []
    if whys:
        out.append("### Why the defaults\n\n" + "\n\n".join(whys))
    if group.subheading:
        out.append(group.subheading)
    out += [family_md(f, res) for f, res in items]
    out += [f"**{k}**: results of a family this version of bench/registry.py does not declare (not shown)"
            for k in unknown]
    out.append(column_notes(items))
    return "\n\n".join(p for p in out if p)


def load_sentence(results: Result) -> str:
    """What the load averages recorded around the run say about other jobs on the machine."""
    load = results.get("load_average")
    if not load:
        return "The machine's load was not recorded during this run: read ratios, not absolute numbers."
    note = load_note(load["before"], load["after"], results["machine"]["cores"])
    return note[0].upper() + note[1:] + "."


def _head(results: Result, docs: bool) -> list[str]:
    m = results["machine"]
    head = "# Benchmarks: what accuracy costs in time\n\n" if docs else f"# s2cl benchmark — {m['machine']}\n\n"
    command = f"python -m bench{' --quick' if results['quick'] else ''}"
    out = [head + f"Measured on {m['cpu']} ({m['cores']} cores), OpenCL device `{m.get('opencl_device', '?')}`, "
           f"{m['date']}; `{command}` took {results['seconds_total']:.0f} s. Times are medians of repeats in one "
           f"process. {load_sentence(results)} "
           "Nothing here asserts a timing; every benchmark first validates a slice against the float64 reference "
           "and stops if it disagrees."]
    if docs:
        took = f", {results['seconds_total']:.0f} s in the run above"
        full, quick = ("", took) if results["quick"] else (took, "")
        out.append(f"Regenerate with `python -m bench` (the full suite{full}; it rewrites this page and "
                   f"`docs/bench/*.png`) or `python -m bench --quick` (reduced sizes{quick}; "
                   "add `--docs` to rewrite this page with its numbers); `--only NAME` runs one part (`python -m "
                   "bench --list`). Every run writes `bench/results/<machine>-<date>[-quick].{json,md}` and its "
                   "plots; `--report RESULT.json` re-renders them. Generated file: the families, their columns and "
                   "plots are declared in `bench/registry.py`, the layout in `bench/report.py`; edit those, not "
                   "this page.")
    return out


def markdown(results: Result, figures: dict[str, str], *, docs: bool = False) -> str:
    """The report; ``figures``: group key → the figure's path relative to the Markdown file."""
    out = _head(results, docs)
    for g in GROUPS:
        if results.get(g.key):
            out.append(group_md(g, results, figures.get(g.key), docs=docs))
        if docs and g.key == "knobs" and (design := design_report.docs_section()):
            out.append(design)  # python -m bench.design_knobs's section, kept when this page is regenerated
    if results.get("validation"):
        out.append("## Validation before timing\n\n" + table(
            (Column("check", "check", ""), Column("value", "value", "")), {},
            [{"check": k, "value": v} for k, v in results["validation"].items()]))
    return "\n\n".join(out) + "\n"


def _write(results: Result, folder: Path, md: Path, prefix: str, link: str, docs: bool) -> list[Path]:
    """Every group's figure as ``folder/<prefix><suffix>.png`` and the Markdown ``md`` linking them."""
    written, figures = [], {}
    for g in GROUPS:
        if g.figure and (p := group_figure(g, group_items(results, g)[0], folder / f"{prefix}{g.figure.suffix}.png")):
            written.append(p)
            figures[g.key] = link + p.name
    return [*written, write_text(md, markdown(results, figures, docs=docs))]


def write_reports(results: Result, out_dir: Path, stem: str, *, docs: bool) -> list[Path]:
    """``<stem>.md`` and ``<stem>-<figure>.png`` in ``out_dir``; with ``docs`` also docs/bench.md and
    docs/bench/<figure>.png."""
    written = _write(results, out_dir, out_dir / f"{stem}.md", f"{stem}-", "", False)
    if docs:
        written += _write(results, DOCS / "bench", DOCS / "bench.md", "", "bench/", True)
    return written
