"""A sweep chunk's device memory, from the kernels' argument declarations (:attr:`s2cl.cl.kernel_args.Arg.scales`):
the sweep kernel's tables, held through the run, and its per-pixel outputs per configuration of a launch; where the
metrics run on the device, the metrics kernel's rows, scratch and target. Known before the tables are built, so the
chunk is sized (:func:`s2cl.app.sweep_budget.sweep_resources`) before anything is computed."""

from __future__ import annotations

from dataclasses import dataclass

from s2cl.cl.device_memory import DeviceBuffer
from s2cl.cl.kernel_args import buffers
from s2cl.cl.vectypes import VALID_LANES
from s2cl.forward.stages import Stage
from s2cl.retrieve.metric import Metric
from s2cl.sweep.kernel import kernel_args
from s2cl.sweep.metrics_kernel import ARGS as METRICS_ARGS

#: the unit a sweep's device memory grows with: the configurations of one launch (a chunk)
UNIT = "configs"


@dataclass(frozen=True)
class SweepSizes:
    """The sizes a sweep's buffers scale with: ``variants`` over all band slots, library ``spectra``, noise
    ``copies`` of each, band ``slots``, SAM ``classes`` (0: a regression), pixels per work-item ``lanes`` (None:
    the widest a device may take, an upper bound)."""

    variants: int
    spectra: int
    copies: int
    slots: int
    classes: int = 0
    lanes: int | None = None

    @property
    def pixels(self) -> int:
        return self.spectra * self.copies

    @property
    def pitch(self) -> int:
        """Pixels per row of a kernel's per-pixel buffers: the pixels padded to whole work-items."""
        lanes = self.lanes or max(VALID_LANES)
        return max(-(-self.pixels // lanes) * lanes, lanes)

    def named(self, metric: Metric) -> dict[str, int]:
        """The sizes by the names the argument declarations use."""
        return {"pitch": self.pitch, "variants": self.variants, "spectra": self.spectra, "slots": self.slots,
                "classes": self.classes, "pixels": self.pixels,
                "columns": len(metric.columns), "scratch": self.pixels if metric.pixel_scratch else 0}


def sweep_device_buffers(stages: list[Stage], sizes: SweepSizes, *, real_bytes: int, device_metrics: bool,
                         metric: Metric) -> list[DeviceBuffer]:
    """The device buffers of a sweep over ``sizes`` with the chain's ``stages`` in ``real_bytes`` floats, each as
    fixed bytes plus bytes per configuration of a chunk; ``device_metrics``: the metrics kernel runs too, with
    ``metric``'s columns and scratch."""
    args = list(kernel_args(stages))
    if device_metrics:
        args += [a for a in METRICS_ARGS if a.name not in {b.name for b in args}]
    return buffers(args, sizes.named(metric), real_bytes, UNIT)
