"""Host side of ``kernels/sweep.cl.mako``: evaluates chunks of sweep configurations on the device."""

from __future__ import annotations

import numpy as np

from s2cl.cl.runtime import Runtime, get_runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import VecTypes
from s2cl.errors import DeviceError, InputError
from s2cl.reference.sweep import RawChunk
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.status import MAX_ABS_REFLECTANCE
from s2cl.sweep.tables import SweepTables

TEMPLATE = "sweep.cl.mako"


class SweepKernel:
    """The fused per-configuration kernel for one sweep's tables and analysis."""

    def __init__(self, tables: SweepTables, analysis: AnalysisSettings, *, precision: str = "float32",
                 device: str | None = None, runtime: Runtime | None = None, lanes: int | None = None):
        self.rt = runtime or get_runtime(device)
        if precision == "float64" and not self.rt.has_fp64:
            raise DeviceError(f"{self.rt.name} has no float64 support (cl_khr_fp64)")
        self.tables, self.analysis = tables, analysis
        self.T = VecTypes(precision, self.rt.lanes(precision, lanes))
        t = tables
        self.pitch = max(-(-t.n_pixels // self.T.lanes) * self.T.lanes, self.T.lanes)
        counts = list(t.counts)
        strides = [int(np.prod(counts[k + 1:])) for k in range(len(counts))]
        row0 = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int).tolist()
        variables = dict(T=self.T, T1=VecTypes(precision, 1), n_slots=t.n_slots, counts=counts, strides=strides,
                         row0=row0, var0=row0, n_spectra=t.n_spectra, copies=t.copies, pitch=self.pitch,
                         lmin=[float(v) for v in t.lmin], lmax=[float(v) for v in t.lmax], maxdn=t.maxdn,
                         noise=t.noise, quantise=t.quantise, kind=analysis.kind, nir=analysis.nir_slot,
                         swir=analysis.swir_slot, n_classes=len(t.class_names), cos_min=self._cos_min(),
                         max_abs=MAX_ABS_REFLECTANCE)
        variables.update(self._igrm_variables(precision))
        self.source = render(TEMPLATE, **variables)
        self.kernel = self.rt.kernel(self.rt.build(self.source, template=TEMPLATE), "sweep_configs")
        self._upload()

    def _cos_min(self) -> float:
        """cos of the SAM angle threshold; -2 (below -1) for none."""
        a = self.analysis.angle_threshold_deg
        return -2.0 if a is None else float(np.cos(np.deg2rad(a)))

    def _igrm_variables(self, precision: str) -> dict:
        if self.analysis.kind != "igrm":
            return {"c": None, "exp_coef": None, "exp_consts": None}
        from s2cl.cl.vecmath import exp_template_vars
        from s2cl.retrieve.igrm import EXP_DEGREE, IgrmSettings, kernel_config

        settings = IgrmSettings.from_mapping(dict(self.analysis.igrm))
        c = kernel_config(settings, self.tables.n_slots, precision, "poly")
        return {"c": c, **exp_template_vars(precision, EXP_DEGREE[precision])}

    def _upload(self) -> None:
        t, dtype, rt = self.tables, self.T.dtype, self.rt
        z = np.zeros((t.n_slots, self.pitch), dtype)
        z[:, : t.n_pixels] = t.z
        refs = np.concatenate(t.references) if t.references else np.zeros(1)
        self.buffers = {
            "radiance": rt.to_device(np.concatenate(t.radiance).astype(dtype)),
            "sigma": rt.to_device(np.concatenate(t.sigma).astype(dtype)),
            "z": rt.to_device(z),
            "centre": rt.to_device(np.concatenate(t.centre).astype(dtype)),
            "lp": rt.to_device(np.concatenate(t.lp).astype(dtype)),
            "g": rt.to_device(np.concatenate(t.g).astype(dtype)),
            "s": rt.to_device(np.concatenate(t.s).astype(dtype)),
            "refs": rt.to_device(refs.astype(dtype)),
        }

    def __call__(self, start: int, stop: int) -> RawChunk:
        """Per-pixel results of configurations ``start … stop-1``."""
        n = stop - start
        if n <= 0 or stop > self.tables.n_configs:
            raise InputError(f"configurations {start}–{stop} outside 0–{self.tables.n_configs}")
        rt, dtype, pitch = self.rt, self.T.dtype, self.pitch
        index_d = rt.empty(n * pitch * dtype.itemsize)
        status_d, bounds_d, cond_d = rt.empty(n * pitch), rt.empty(n * pitch), rt.empty(n * pitch)
        b = self.buffers
        self.kernel(rt.queue, (pitch // self.T.lanes, n), None, index_d, status_d, bounds_d, cond_d, b["radiance"],
                    b["sigma"], b["z"], b["centre"], b["lp"], b["g"], b["s"], b["refs"], np.uint32(start),
                    np.uint32(n))
        m = self.tables.n_pixels
        index = rt.fetch(index_d, (n, pitch), dtype)[:, :m].astype(np.float64)
        status = rt.fetch(status_d, (n, pitch), np.uint8)[:, :m]
        bounds = rt.fetch(bounds_d, (n, pitch), np.uint8)[:, :m]
        condition = rt.fetch(cond_d, (n, pitch), np.uint8)[:, :m]
        return RawChunk(start, stop, index, status, bounds, condition)
