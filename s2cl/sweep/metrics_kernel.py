"""Host side of ``kernels/metrics.cl.mako``: a sweep chunk's per-configuration metrics on the device.

The sweep kernel leaves its per-pixel outputs (index, status, bounds, condition) on the device; this
kernel reduces them to one row of metrics per configuration, so only those rows travel back. The
definitions are :mod:`s2cl.retrieve.metrics` (the float64 numpy twin): rows the kernel marks (singular
normal equations, fewer than three regression pixels) are recomputed there from their fetched pixels.
Needs float64 on the device (``cl_khr_fp64``); without it the engine computes every row on the host.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.sweep.raw import RawChunk

TEMPLATE = "metrics.cl.mako"
#: (the sweep kernel's outputs it reads are that kernel's buffers: their sizes are declared there; ``scratch``: the
#: regression's median copy, ``scratch`` pixels per configuration, none for a classification)
ARGS = (Arg("out", "out", "double", ("configs", "columns")), Arg("scratch", "inout", "double", ("configs", "scratch")),
        Arg("index", "in", "real"), Arg("status", "in", "uchar"), Arg("bounds", "in", "uchar"),
        Arg("condition", "in", "uchar"), Arg("target", "in", "double", ("pixels",)), Arg("n_configs", "scalar", "uint"))


class MetricsKernel:
    """Per-configuration metrics of ``analysis`` over ``n_pixels`` pixels (rows ``pitch`` apart) on ``rt``.

    :param T: the sweep kernel's types (the index arrives in its precision).
    :param target: per-pixel regression target, or SAM truth class (``(n_pixels,)``).
    """

    def __init__(self, rt: Runtime, T: VecTypes, analysis: AnalysisSettings, target: np.ndarray, pitch: int,
                 n_classes: int = 0):
        self.rt, self.T, self.analysis, self.pitch = rt, T, analysis, pitch
        self.metric = analysis.family.metric  # its output columns: metric.columns ("host": recomputed on the host)
        self.names = self.metric.columns
        self.condition = analysis.family.has_condition
        self.n_pixels = int(np.asarray(target).size)
        self.n_classes = n_classes
        source = render(TEMPLATE, T=T, kind=self.metric.name, names=self.names,
                        n_pixels=self.n_pixels, pitch=pitch, regress=tuple(int(r) for r in analysis.regress),
                        condition=self.condition, n_classes=n_classes, args=ARGS, signature=signature)
        program = rt.build(source, template=TEMPLATE)
        self.kernel = rt.kernel(program, self.metric.kernel_name)
        self.target = np.ascontiguousarray(target, dtype=np.float64)
        self._target_d = rt.to_device(self.target)

    @staticmethod
    def available(rt: Runtime) -> bool:
        """Whether ``rt``'s device can run it (float64); whether a sweep's metrics do: :func:`metrics_on_device`."""
        return bool(rt.has_fp64)

    def __call__(self, buffers: dict[str, Any], n_configs: int, fetch_rows: Any) -> dict[str, np.ndarray]:
        """Metrics of ``n_configs`` configurations from the sweep kernel's device ``buffers`` (index,
        status, bounds, condition); ``fetch_rows(rows)`` returns a :class:`RawChunk` of those rows for the
        host's recomputation of marked ones."""
        rt, width = self.rt, len(self.names)
        values = {"out": rt.alloc(n_configs * width * 8), "target": self._target_d, "n_configs": n_configs,
                  "scratch": rt.alloc(max(1, n_configs * self.n_pixels if self.metric.pixel_scratch else 0) * 8),
                  **{k: buffers[k] for k in ("index", "status", "bounds", "condition")}}
        # named work-groups: left to itself, PoCL makes one group of all the configurations, which one thread runs
        self.kernel(rt.queue, (n_configs,), rt.local_size(self.kernel, n_configs), *bind(ARGS, values, self.T))
        table = rt.fetch(values["out"], (n_configs, width), np.float64)
        rows = {name: table[:, k].copy() for k, name in enumerate(self.names) if name != "host"}
        rows["n_valid"] = rows["n_valid"].astype(np.int64) if "n_valid" in rows else None
        if "constant_index" in rows:
            rows["constant_index"] = rows["constant_index"] != 0.0
        if not self.condition and "log10_condition_median" in rows:
            del rows["log10_condition_median"]
        rows = {k: v for k, v in rows.items() if v is not None}
        marked = np.flatnonzero(table[:, self.names.index("host")] != 0.0)
        if marked.size:
            redo = self.host_metrics(fetch_rows(marked))
            for k in rows:
                rows[k][marked] = np.asarray(redo[k])
        return rows

    def host_metrics(self, raw: RawChunk) -> dict[str, np.ndarray]:
        """The numpy twin's metrics of ``raw`` (the same columns)."""
        return host_metrics(self.analysis, raw, self.target, self.n_classes)


def metrics_on_device(rt: Runtime, *, distributed: bool = False) -> bool:
    """Where a sweep's per-configuration metrics run, decided here only: on ``rt``'s device (this kernel, only the
    metric rows come back) when it has float64 (:meth:`MetricsKernel.available`) and the chunks are evaluated in this
    process; else in numpy on the host (``distributed``: Dask workers evaluate them, on devices this process does
    not see, so the host's memory is planned for). The engine (:meth:`s2cl.sweep.kernel.SweepKernel.metrics`) and the
    memory plan (:func:`s2cl.app.sweep_budget.sweep_resources`' ``host_metrics``) both ask it."""
    return MetricsKernel.available(rt) and not distributed


def host_metrics(analysis: AnalysisSettings, raw: RawChunk, target: np.ndarray, n_classes: int
                 ) -> dict[str, np.ndarray]:
    """Per-configuration metrics of ``raw`` in numpy (:mod:`s2cl.retrieve.metrics`)."""
    m = analysis.family.metric.metrics(raw.index, raw.status, raw.bounds, target, regress=analysis.regress,
                                       n_classes=n_classes,
                                       condition=raw.condition if analysis.family.has_condition else None)
    m.pop("confusion", None)  # a classification's confusion matrices: not a column
    return m
