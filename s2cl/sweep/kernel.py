"""Host side of ``kernels/sweep.cl.mako``: evaluates chunks of sweep configurations on the device."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes
from s2cl.errors import InputError
from s2cl.forward.stages import Stage, Value, inputs, segments, stage
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.family import SweepContext
from s2cl.status import MAX_ABS_REFLECTANCE
from s2cl.sweep.metrics_kernel import MetricsKernel, host_metrics, metrics_on_device
from s2cl.sweep.raw import RawChunk
from s2cl.sweep.tables import SweepTables

TEMPLATE = "sweep.cl.mako"
#: the per-pixel outputs of every sweep kernel, in the kernel's argument order
PER_LAUNCH = ("configs", "pitch")
OUTPUTS = (Arg("index", "out", "real", PER_LAUNCH), Arg("status", "out", "uchar", PER_LAUNCH),
           Arg("bounds", "out", "uchar", PER_LAUNCH), Arg("condition", "out", "uchar", PER_LAUNCH))
#: profile builds (the ``profile`` switches of kernels/sweep.cl.mako; bench/sweep_profile.py times them): none
#: is ever part of a sweep's kernel
PROFILES = ("iterations", "reflectance", "no_fit", "fit_only")
#: the extra arguments of the profile switches that have one
PROFILE_ARGS = {"reflectance": Arg("rho_out", "out", "real", ("configs", "slots", "pitch")),
                "fit_only": Arg("rho_in", "in", "real", ("configs", "slots", "pitch"))}
#: the sizes of a sweep table that varies per variant and spectrum, or per variant
_TABLE_SCALES = {"pixel": ("variants", "spectra"), "variant": ("variants",)}


def kernel_args(stages: list[Stage], profile: frozenset[str] = frozenset()) -> tuple[Arg, ...]:
    """The kernel's arguments for the chain's ``stages`` and a build with the ``profile`` switches: the outputs, the
    radiance table, each stage's per-pixel and per-variant tables, the deviates (where a stage takes them), the
    band centres, the SAM references, the configuration range."""
    tables = [Arg(v.name, "in", v.ctype, _TABLE_SCALES[v.varies]) for v in inputs(stages, "sweep")
              if v.varies in _TABLE_SCALES]
    deviates = [Arg("z", "in", "real", ("slots", "pitch"))] if any(s.deviates for s in stages) else []
    return (*OUTPUTS, Arg("radiance", "in", "real", ("variants", "spectra")), *tables, *deviates,
            Arg("centre", "in", "real", ("variants",)), Arg("refs", "in", "real", ("variants", "classes")),
            Arg("config_start", "scalar", "uint"), Arg("n_configs", "scalar", "uint"),
            *(PROFILE_ARGS[p] for p in PROFILES if p in profile and p in PROFILE_ARGS))


@dataclass(frozen=True)
class VectorCode:
    """OpenCL C of ``T.lanes`` pixels per work-item: gathers from a per-spectrum table, vector loads and stores,
    one lane of a vector."""

    T: VecTypes

    def gather(self, table: str, row: str) -> str:
        L = self.T.lanes
        if L == 1:
            return f"{table}[{row} + sp0]"
        return f"({self.T.V})(" + ", ".join(f"{table}[{row} + sp{lane}]" for lane in range(L)) + ")"

    def vload(self, ptr: str) -> str:
        return f"{ptr}[0]" if self.T.lanes == 1 else f"vload{self.T.lanes}(0, {ptr})"

    def vstore(self, value: str, ptr: str) -> str:
        return f"{ptr}[0] = {value};" if self.T.lanes == 1 else f"vstore{self.T.lanes}({value}, 0, {ptr});"

    def lane(self, expr: str, lane: int) -> str:
        return expr if self.T.lanes == 1 else f"({expr}).s{'0123456789abcdef'[lane]}"


@dataclass(frozen=True)
class SweepSite:
    """Where slot ``k``'s steps run in the sweep kernel (see ``kernels/common/stages.mako``): a per-band value is a
    literal (every variant takes its band's), a per-variant one the table entry of the variant (``[var]``), a
    per-pixel one a gather from the per-spectrum table (``row``); no output is written."""

    vc: VectorCode
    k: int
    pitch: int
    values: dict[str, Value]
    literals: dict[str, Any]

    def has(self, name: str) -> bool:
        return name in self.values

    def value(self, name: str) -> str:
        v, T = self.values[name], self.vc.T
        if v.varies == "band":
            return T.lit(float(self.literals[name][self.k]))
        if v.varies == "scalar":
            return T.lit(float(self.literals[name]))
        if v.varies == "variant":
            return f"{name}[var]"
        return self.vc.gather(name, "row")

    def store(self, name: str, expr: str) -> str:
        return ""

    def deviate(self) -> str:
        return self.vc.vload(f"(z + {self.k}u * {self.pitch}u + p0)")


@dataclass(frozen=True)
class SweepAcross:
    """Where a stage across the slots runs in the sweep kernel: on ``X[0 … n-1]``, its pair values as literals."""

    T: VecTypes
    n: int
    literals: dict[str, Any]

    def pairs(self, name: str) -> list[list[float]]:
        return [[float(x) for x in row] for row in np.asarray(self.literals[name])]

    def store(self, name: str, k: int, expr: str) -> str:
        return ""


#: configuration numbers the kernel addresses (``config_start`` and ``n_configs`` are 32-bit): a design numbered
#: beyond is scored through tables of its own (:mod:`s2cl.sweep.designs`), as every given design is
KERNEL_CONFIGS = 2**32 - 1

#: work-items per group at most: PoCL's own choice for few pixels and many configurations (e.g. 8 × 512 items for
#: 120 pixels × 1,024 configurations) crashed the kernel; groups this small measured no slower
MAX_GROUP = 64


def work_group(blocks: int) -> tuple[int, int]:
    """The work-group of a launch of ``blocks`` pixel blocks: the largest power of two up to :data:`MAX_GROUP`
    that divides ``blocks``, times configurations up to :data:`MAX_GROUP` items in all."""
    g = 1
    while g * 2 <= MAX_GROUP and blocks % (g * 2) == 0:
        g *= 2
    return g, MAX_GROUP // g


class SweepKernel:
    """The fused per-configuration kernel for one sweep's tables and analysis, on ``rt``'s device."""

    def __init__(self, tables: SweepTables, analysis: AnalysisSettings, rt: Runtime, *, precision: str = "float32",
                 lanes: int | None = None, profile: frozenset[str] = frozenset()):
        unknown = sorted(set(profile) - set(PROFILES))
        if unknown or ("iterations" in profile and not analysis.family.iterative) or {"no_fit", "fit_only"} <= profile:
            raise InputError(f"profile switches {sorted(profile)}: allowed {', '.join(PROFILES)} (iterations: an "
                             "iterative fit only; not no_fit with fit_only)")
        self.profile = frozenset(profile)
        self.rt = rt
        self.tables, self.analysis = tables, analysis
        self.T = rt.types(precision, lanes)
        t = tables
        self.pitch = max(-(-t.n_pixels // self.T.lanes) * self.T.lanes, self.T.lanes)
        counts = list(t.counts)
        # a design list (diagonal tables): every slot takes variant cfg
        strides = [1] * len(counts) if t.diagonal else [int(np.prod(counts[k + 1:])) for k in range(len(counts))]
        row0 = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int).tolist()
        ctx = SweepContext(tuple(t.bands), tuple(counts), tuple(strides), tuple(row0), len(t.class_names),
                           MAX_ABS_REFLECTANCE)
        functions, body = analysis.family.sweep_code(analysis, self.T, ctx)
        self.stages = [stage(n) for n in t.stages]
        self.args = kernel_args(self.stages, self.profile)
        values = {v.name: v for v in t.inputs()}
        literals = {n: t.values[n] for n, v in values.items() if v.varies in ("band", "scalar", "pairs")}
        vc = VectorCode(self.T)
        variables = dict(T=self.T, n_slots=t.n_slots, counts=counts, strides=strides, row0=row0, var0=row0,
                         n_spectra=t.n_spectra, copies=t.copies, pitch=self.pitch, stages=self.stages,
                         segments=segments(self.stages), vc=vc,
                         site=lambda k: SweepSite(vc, k, self.pitch, values, literals),
                         across=SweepAcross(self.T, t.n_slots, literals), analysis_functions=functions,
                         analysis_body=body, profile=self.profile, args=self.args, signature=signature)
        self.source = render(TEMPLATE, **variables)
        self.kernel = self.rt.kernel(self.rt.build(self.source, template=TEMPLATE), "sweep_configs")
        self._upload()
        self._metrics = None  # the metrics kernel, built on first use
        self._launched = 0  # configurations of the last launch (the size of the buffers the pool holds)

    def _upload(self) -> None:
        t, dtype, rt = self.tables, self.T.dtype, self.rt
        refs = np.concatenate(t.references) if t.references else np.zeros(1)
        self.buffers = {
            "radiance": rt.to_device(np.concatenate(t.radiance).astype(dtype)),
            **{n: rt.to_device(np.concatenate(t.values[n]).astype(dtype)) for n in t.per_row()},
            "centre": rt.to_device(np.concatenate(t.centre).astype(dtype)),
            "refs": rt.to_device(refs.astype(dtype)),
        }
        if any(s.deviates for s in self.stages):
            z = np.zeros((t.n_slots, self.pitch), dtype)
            z[:, : t.n_pixels] = t.z
            self.buffers["z"] = rt.to_device(z)

    def load(self, tables: SweepTables) -> None:
        """Evaluate ``tables`` from now on: tables of the same shape (a search's next batch of designs on the same
        copies, :mod:`s2cl.sweep.design_tables`), so the built kernels and the metrics' target stay valid."""
        t = self.tables
        if (tables.counts != t.counts or tables.n_pixels != t.n_pixels or tables.diagonal != t.diagonal
                or tables.stages != t.stages):
            raise ValueError("tables of another shape need their own kernel")
        self.tables = tables
        self._upload()

    def _launch(self, start: int, stop: int, extra: dict | None = None) -> dict:
        """Run configurations ``start … stop-1``; their per-pixel outputs stay on the device. ``extra``: the
        profile switches' buffers (:data:`PROFILE_ARGS`)."""
        n = stop - start
        if n <= 0 or stop > self.tables.n_configs:
            raise InputError(f"configurations {start}–{stop} outside 0–{self.tables.n_configs}")
        rt, T, pitch = self.rt, self.T, self.pitch
        if n != self._launched:  # the pool's buffers of another size go back: it holds one launch's, not two
            rt.free_held()
            self._launched = n
        out = {"index": rt.alloc(n * pitch * T.dtype.itemsize), "status": rt.alloc(n * pitch),
               "bounds": rt.alloc(n * pitch), "condition": rt.alloc(n * pitch)}
        if "reflectance" in self.profile:
            out["rho_out"] = rt.alloc(n * self.tables.n_slots * pitch * T.dtype.itemsize)
        values = {**out, **self.buffers, **(extra or {}), "config_start": start, "n_configs": n}
        local = work_group(pitch // T.lanes)
        configs = -(-n // local[1]) * local[1]  # the kernel returns for configurations past n_configs
        self.kernel(rt.queue, (pitch // T.lanes, configs), local, *bind(self.args, values, T))
        return out

    def _fetch(self, out: dict, start: int, stop: int, rows: np.ndarray | None = None) -> RawChunk:
        n, m, pitch, T = stop - start, self.tables.n_pixels, self.pitch, self.T
        sel = slice(None) if rows is None else rows
        index = self.rt.fetch(out["index"], (n, pitch), T.dtype)[sel, :m]
        status, bounds, condition = (self.rt.fetch(out[k], (n, pitch), np.uint8)[sel, :m]
                                     for k in ("status", "bounds", "condition"))
        return RawChunk(start, stop, index, status, bounds, condition)

    def __call__(self, start: int, stop: int) -> RawChunk:
        """Per-pixel results of configurations ``start … stop-1`` (index in float64)."""
        raw = self._fetch(self._launch(start, stop), start, stop)
        raw.index = raw.index.astype(np.float64)
        return raw

    def metrics(self, start: int, stop: int) -> dict[str, np.ndarray]:
        """Per-configuration metrics of configurations ``start … stop-1`` (:mod:`s2cl.retrieve.metrics`):
        where :func:`s2cl.sweep.metrics_kernel.metrics_on_device` says: on the device (only the metric rows
        return), else in numpy on the host."""
        t = self.tables
        out = self._launch(start, stop)
        if not metrics_on_device(self.rt):
            return host_metrics(self.analysis, self._fetch(out, start, stop), t.target, len(t.class_names))
        if self._metrics is None:
            self._metrics = MetricsKernel(self.rt, self.T, self.analysis, t.target, self.pitch, len(t.class_names))
        return self._metrics(out, stop - start, lambda rows: self._fetch(out, start, stop, rows))
