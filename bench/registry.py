"""The benchmark families, each declared once: how it runs (its full and ``--quick`` sizes), its
result columns (key, name, unit, what it means) and how it is plotted.

``python -m bench`` runs the families of :data:`FAMILIES` (``--only NAME``, ``--list``) and
:mod:`bench.report` renders a results JSON from this list alone. Adding a family is adding one
:class:`Family` to :data:`FAMILIES` and the function it runs, e.g. a GVMI throughput series::

    Family("gvmi", SCALING, "GVMI (2 bands, float32)", scaling.gvmi_vs_pixels, SERIES, LOGLOG,
           full={"pixels": 10**6}, quick={"pixels": 10**5}, rows="points", caption=series_caption)

The function is called as ``run(ctx, **sizes)`` (:class:`bench.chain.Context`, the sizes of this
run); it validates against float64 references before it times anything and returns the family's
result (JSON): its table rows under ``rows`` (holding the columns' keys), and ``validation*`` keys,
which the suite gathers into the report's validation table.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from bench import bench_igrm, bench_resample, bench_sam, knobs, plots, scaling, why
from bench.common import fmt_number

Row = dict[str, Any]
Result = dict[str, Any]


@dataclass(frozen=True)
class Column:
    """One column of a family's table.

    :param key: the row's key (the value shown unless ``cell`` computes it).
    :param name: the heading; ``{field}`` is filled from the family's result (e.g. ``{unit}``).
    :param doc: what the column means (the report's column notes, ``--list``).
    :param unit: shown as ``name [unit]``.
    :param scale: the stored value times ``scale`` is shown (seconds as ms: 1e3).
    :param digits: significant digits (:func:`bench.common.fmt_number`).
    :param optional: left out of a table in which every row's value is missing or zero.
    :param missing: what a row without ``key`` shows (None: "–").
    """

    key: str
    name: str
    doc: str
    unit: str = ""
    scale: float = 1.0
    digits: int = 3
    optional: bool = False
    missing: Any = None
    cell: Callable[[Row], Any] | None = None

    def header(self, result: Result) -> str:
        name = self.name.format_map(result)
        return f"{name} [{self.unit}]" if self.unit else name

    def value(self, row: Row) -> Any:
        v = self.cell(row) if self.cell else row.get(self.key, self.missing)
        return v * self.scale if self.scale != 1 and isinstance(v, int | float) and not isinstance(v, bool) else v

    def text(self, row: Row) -> str:
        return fmt_number(self.value(row), self.digits)


@dataclass(frozen=True)
class Panel:
    """An axis of its group's figure: ``draw(ax, [(title, result), ...])`` (:mod:`bench.plots`). A
    shared panel holds every family that names it, under its own ``title``; otherwise each family
    gets an axis titled with the family's title."""

    draw: Callable[[Any, list[tuple[str, Result]]], None]
    title: str = ""
    shared: bool = False


@dataclass(frozen=True)
class Figure:
    """A group's figure: ``<stem>-<suffix>.png`` beside the report (and ``docs/bench/<suffix>.png``)."""

    suffix: str
    alt: str
    size: tuple[float, float]  # inches per axis
    columns: int  # axes per row at most
    suptitle: str | None = None


@dataclass(frozen=True)
class KeyTable:
    """A group's summary table: each family's default row and its ``key_settings`` rows, after a
    first row with the time of the reference that the ``key_reference`` families share."""

    reference: str  # that reference, in words
    note: str  # printed under the table


@dataclass(frozen=True)
class Group:
    """A section of the results JSON and of the report (and ``--only NAME`` for all its families)."""

    key: str
    heading: str
    caption: Callable[[Family, Result], str]  # above a family's table, unless the family has its own
    intro: Callable[[Result], str] | None = None  # under the heading, from the whole results
    prefix: str = ""  # a family's part name is prefix + key
    figure: Figure | None = None
    key_table: KeyTable | None = None
    subheading: str | None = None  # above the families' tables


@dataclass(frozen=True, eq=False)
class Family:
    """One benchmark family; see the module for how it is run and what it returns."""

    key: str  # its key in the group's section of the results JSON
    group: Group
    title: str
    run: Callable[..., Result]
    columns: tuple[Column, ...]
    panel: Panel | None = None
    full: Mapping[str, Any] = field(default_factory=dict)  # keyword sizes of the full suite
    quick: Mapping[str, Any] = field(default_factory=dict)  # ... and of --quick
    rows: str = "rows"  # the result's list of table rows
    caption: Callable[[Family, Result], str] | None = None
    key_settings: tuple[str, ...] = ()  # settings (prefixes) of the key table besides the default
    key_reference: bool = False  # its reference row is the key table's reference
    accuracy: Callable[[Row], str] | None = None  # a row's "accuracy lost", in words (key table)
    why: Callable[[Result], str | None] | None = None  # the paragraph arguing its default (docs)

    @property
    def name(self) -> str:
        """The part name (``--only``, ``--list``, the results' ``parts`` and ``seconds``)."""
        return self.group.prefix + self.key

    def sizes(self, quick: bool) -> dict[str, Any]:
        return dict(self.quick if quick else self.full)

    def table_caption(self, result: Result) -> str:
        return (self.caption or self.group.caption)(self, result)


# -- cells, captions, accuracy phrases ----------------------------------------------------------------

def setting_cell(r: Row) -> str:
    tags = [t for t, k in (("**default**", "default"), ("*reference*", "reference")) if r.get(k)]
    return r["setting"] + (" " + " ".join(tags) if tags else "")


def method_cell(r: Row) -> str:
    return r["method"] + (" *(baseline)*" if r.get("baseline") else "")


def chain_accuracy(r: Row) -> str:
    parts = []
    if r.get("err_radiance_ner_max"):
        parts.append(f"radiance {r['err_radiance_ner_max']:.2g} NER")
    if r.get("err_lp_rms_nm") is not None:
        parts.append(f"lp {r['err_lp_rms_nm']:.2g} nm")
    if r.get("err_rms_cab") is not None:
        parts.append(f"Cab RMS {r['err_rms_cab']:.1g} ug/cm2")
    return ", ".join(parts)


def copies_accuracy(r: Row) -> str:
    return f"Cab RMS known to ±{r['ci95_halfwidth']:.3f} ug/cm2 (95 %)"


def knob_caption(f: Family, r: Result) -> str:
    extra = "".join(f" {r[k]}." for k in ("timed", "note") if r.get(k))
    return f"#### {f.title}\n\nReference: {r['reference']}.{extra}"


def series_caption(f: Family, s: Result) -> str:
    note = f" — {s['note']}" if s.get("note") else ""
    return f"**{f.title}** vs {s['x']}: log–log slope **{s['slope']:.2f}**{note}"


def memory_caption(f: Family, s: Result) -> str:
    return f"**{f.title}** ({s['pixels_per_config']} pixels per configuration): {s['note']}"


def dask_caption(f: Family, s: Result) -> str:
    return (f"**{f.title}** ({s['configurations']} configurations × {s['pixels_per_config']} pixels, chunk "
            f"{s['chunk']}): {s['note']}")


def baseline_caption(f: Family, b: Result) -> str:
    return f"**{b.get('title', f.title)}** ({fmt_number(b['n'])} items, medians)"


def knobs_intro(results: Result) -> str:
    c = results["context"]
    return ("Each knob is moved alone from the default scene (Lib1 slice of "
            f"{c['spectra']} PROSAIL canopies × {c['copies']} noisy copies "
            "through the whole chain and an IGRM chlorophyll fit on B4 B5 B6 B8). Accuracy is measured against "
            "the all-accurate reference (float64 kernels, 1 nm grid, SRF on ±3 FWHM, converged float64 fits, "
            "the paper's atmosphere on exact LUT nodes); time is the chain on "
            f"{c['time_pixels']:,} distinct pixels (image-like: every pixel resampled) unless "
            "a table says otherwise. *NER* = the band's noise-equivalent radiance at that signal: an error "
            "well below 1 NER is invisible under the sensor's own noise. *lp* = IGRM inflection wavelength "
            "(the chlorophyll index); *Cab RMS* = the paper's metric (ug/cm2).")


# -- columns -------------------------------------------------------------------------------------------

SETTING = Column("setting", "setting", "the knob's value; **default**: the shipped setting, *reference*: what the "
                 "knob is scored against", cell=setting_cell)
TIME_MS = Column("seconds", "time", "median wall time of the timed workload", unit="ms", scale=1e3)
CHAIN = (
    SETTING, TIME_MS,
    Column("speedup", "speed-up", "the time of the knob's reference ÷ this setting's time"),
    Column("err_radiance_ner_max", "radiance err / NER (max)", "largest band-radiance error against the reference, "
           "in units of the band's noise-equivalent radiance", optional=True),
    Column("err_radiance_rel_max", "radiance err rel (max)", "largest relative band-radiance error against the "
           "reference", optional=True),
    Column("err_lp_rms_nm", "lp err RMS", "RMS per-pixel difference of the IGRM inflection wavelength lp from "
           "the reference's", unit="nm"),
    Column("rms_cab", "Cab RMS", "RMS error of the retrieved chlorophyll against the library's", unit="ug/cm2"),
    Column("err_rms_cab", "Δ Cab RMS (abs)", "|Cab RMS − the reference's Cab RMS|", unit="ug/cm2"),
)
LM = (*CHAIN, Column("frac_at_optimum", "at optimum", "fraction of fits whose lp is within 0.05 nm of the "
                     "converged float64 fit's"),
      Column("mean_iterations", "mean iter.", "mean LM iterations per fit"))
COPIES = (
    SETTING, TIME_MS,
    Column("speedup", "speed-up vs 1000", "the time of 1000 copies ÷ this setting's time"),
    Column("rms_cab", "mean Cab RMS", "the chlorophyll RMS error, mean over the noise seeds", unit="ug/cm2"),
    Column("rms_cab_sd", "SD over seeds", "its standard deviation over the seeds", unit="ug/cm2"),
    Column("ci95_halfwidth", "95 % CI half-width", "1.96 × SD: how well one run knows the Cab RMS", unit="ug/cm2"),
    Column("seeds", "seeds", "noise seeds run"),
)
SERIES = (Column("x", "{x}", "the problem size (pixels, bands or configurations)"), TIME_MS,
          Column("rate_per_s", "{rate_unit}", "items per second at that size"))
MEMORY = (Column("chunk", "chunk", "configurations per chunk"),
          Column("chunk_rss_mib", "measured", "peak growth of the resident set while the chunk runs (sampled: a "
                 "lower bound)", unit="MiB"),
          Column("estimate_mib", "estimate", "s2cl's planning estimate (host_footprint)", unit="MiB"), TIME_MS)
DASK = (Column("label", "run", "in-process, or Dask with that many workers"),
        Column("seconds", "wall", "wall time, cluster start-up included", unit="s"),
        Column("configs_per_s", "configurations/s", "configurations evaluated per second"))
COMPARISON = (Column("method", "method", "what ran; *(baseline)*: what a user would otherwise run", cell=method_cell),
              Column("per_s", "{unit}", "items per second (median)"),
              Column("ratio_s2cl_over_this", "s2cl ÷ this", "s2cl's rate (the first row) ÷ this row's"),
              Column("frac_at_float64_optimum", "fits at float64 optimum", "fraction of fits at the converged "
                     "float64 optimum (status class, lp, l0, s within 0.05 nm; rmin, rmax within 5e-4)",
                     optional=True),
              Column("note", "note", "", missing=""))

KEY_COLUMNS = (Column("knob", "knob", "the knob (its table below)"),
               Column("setting", "setting", "the default and the telling alternatives"), TIME_MS,
               Column("speedup", "speed-up vs its reference", "the time of the knob's reference ÷ this setting's"),
               Column("accuracy", "accuracy lost", "against the knob's reference"))

# -- groups and families -------------------------------------------------------------------------------

PARETO = Panel(plots.pareto)
LOGLOG = Panel(plots.loglog, "time vs problem size (log–log)", shared=True)
KNOBS = Group(
    "knobs", "What accuracy costs", knob_caption, knobs_intro,
    figure=Figure("pareto", "Pareto plots: error against time per knob", (4.6, 4.0), 4,
                  "What accuracy costs: error against time per knob (★ default, ■ reference, × other SRF model, "
                  "line: Pareto front)"),
    key_table=KeyTable(
        "float64, 1 nm, SRF ±3 FWHM, converged fits",
        "Speed-ups are against each knob's own reference: the all-accurate chain (grid, precision, SRF; time of the "
        "chain), the converged float64 fit of the same input (fit settings; time of the fit alone), the shipped "
        "LUT's exact nodes (LUT; time of computing the terms, once per scene), 1000 copies (copies; the accuracy "
        "column is the confidence the copies buy), the unquantised chain (bits), the atmosphere on (atmosphere). "
        "The full tables per knob follow the plot."),
    subheading="### Per knob")
SCALING = Group("scaling", "Throughput and scaling", series_caption,
                figure=Figure("scaling", "time vs size, memory vs chunk, Dask", (13 / 3, 3.8), 3))
BASELINES = Group("baselines", "Side by side with what a user would otherwise run", baseline_caption, prefix="vs-")
GROUPS = (KNOBS, SCALING, BASELINES)


def _knob(key: str, title: str, run: Callable[..., Result], columns: tuple[Column, ...] = CHAIN,
          **kw: Any) -> Family:
    return Family(key, KNOBS, title, run, columns, PARETO, accuracy=kw.pop("accuracy", chain_accuracy), **kw)


FAMILIES: tuple[Family, ...] = (
    _knob("grid", "Spectral grid step", knobs.knob_grid, key_settings=("1 nm", "5 nm", "10 nm"),
          key_reference=True, why=why.grid),
    _knob("precision", "float32 vs float64", knobs.knob_precision, key_settings=("float64 kernels + float64 fit",),
          key_reference=True, why=why.precision),
    _knob("srf", "SRF support and model vs measured SRF", knobs.knob_srf,
          key_settings=("model SRF ±2 FWHM", "measured S2A"), key_reference=True, why=why.srf),
    _knob("lm", "IGRM fit: iterations, tolerance, initial guess (float32 kernel)", knobs.knob_lm, LM,
          full={"population": 1_000_000}, quick={"population": 200_000},
          key_settings=("initial guess only", "max_iter 10", "max_iter 50", "max_iter 255"), why=why.lm),
    _knob("lut", "Atmosphere LUT interpolation and node density", knobs.knob_lut,
          key_settings=("every other node of all three, linear", "every other node of all three, nearest"),
          why=why.lut),
    _knob("copies", "Noise copies per spectrum", knobs.knob_copies, COPIES, full={"seeds": 30}, quick={"seeds": 10},
          key_settings=("10 copies", "100 copies", "1000 copies"), accuracy=copies_accuracy, why=why.copies),
    _knob("bits", "Quantisation bits", knobs.knob_bits, key_settings=("10 bits", "12 bits", "14 bits"), why=why.bits),
    _knob("atmosphere", "Atmosphere effect on/off", knobs.knob_atmosphere, key_settings=("atmosphere off",),
          why=why.atmosphere),
    Family("forward", SCALING, "forward chain", scaling.forward_vs_pixels, SERIES, LOGLOG,
           full={"block": 100_000}, quick={"block": 50_000}, rows="points"),
    Family("fits", SCALING, "IGRM fit (4 bands, float32)", scaling.fits_vs_pixels, SERIES, LOGLOG, rows="points"),
    Family("bands", SCALING, "SRF resampling", scaling.resample_vs_bands, SERIES, LOGLOG,
           full={"spectra": 100_000}, quick={"spectra": 20_000}, rows="points"),
    Family("configs", SCALING, "sweep (configurations × pixels)", scaling.sweep_vs_configs,
           (*SERIES, Column("config_pixels_per_s", "configuration-pixels/s", "configurations × pixels evaluated per "
                            "second")), LOGLOG, full={"copies": 100}, quick={"copies": 10}, rows="points"),
    Family("memory", SCALING, "Memory vs sweep chunk", scaling.memory_vs_chunk, MEMORY,
           Panel(plots.memory, "memory vs sweep chunk"), full={"copies": 100, "chunks": (16, 64, 256, 1024, 3312)},
           quick={"copies": 10, "chunks": (16, 128, 1024)}, rows="points", caption=memory_caption),
    Family("dask", SCALING, "Dask", scaling.dask_workers, DASK, Panel(plots.dask, "whole sweep: in-process vs Dask "
           "workers"), full={"copies": 100}, quick={"copies": 10}, caption=dask_caption),
    Family("resample", BASELINES, "SRF resampling against numpy and SPy", bench_resample.resample_baseline,
           COMPARISON, full={"spectra": 100_000, "spy_sample": 2000}, quick={"spectra": 20_000, "spy_sample": 500}),
    Family("igrm", BASELINES, "IGRM fits against numpy and scipy", bench_igrm.igrm_baseline, COMPARISON,
           full={"n": 1_000_000, "n_scipy": 1000, "n_numpy": 100_000},
           quick={"n": 100_000, "n_scipy": 200, "n_numpy": 10_000}),
    Family("sam", BASELINES, "SAM against SPy and numpy", bench_sam.sam_baseline, COMPARISON,
           full={"n": 1_000_000, "bands": 13, "refs": 20}, quick={"n": 100_000, "bands": 13, "refs": 20}),
)


def by_name() -> dict[str, Family]:
    """Every family by part name, in suite order."""
    return {f.name: f for f in FAMILIES}


def select(only: list[str] | None) -> list[Family]:
    """The families named by ``--only`` values (part or group names, comma-separated); all without."""
    if not only:
        return list(FAMILIES)
    names, groups = by_name(), {g.key: g for g in GROUPS}
    wanted: list[Family] = []
    for item in (x.strip() for part in only for x in part.split(",")):
        if item in groups:
            wanted += [f for f in FAMILIES if f.group is groups[item]]
        elif item in names:
            wanted.append(names[item])
        else:
            raise SystemExit(f"bench: unknown part {item!r}; choose from {', '.join((*groups, *names))}")
    return list(dict.fromkeys(wanted))
