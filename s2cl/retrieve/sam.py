"""Spectral Angle Mapper classification on the device, confusion matrix and omission error.

Each pixel (band reflectances at sensor resolution) gets the class of the reference spectrum
with the smallest spectral angle ``arccos(p.r / (|p| |r|))``; with a threshold, pixels whose best
angle exceeds it stay unclassified. Several references may share a class (e.g. every Al-OH
mineral of a library as its own reference). The paper scores a band design by the mean
omission error of the confusion matrix (Segl et al. 2012, section 4.2.2).

Hard cases: a pixel with |p| = 0 has no direction (ZERO_VECTOR, unclassified); NaN/inf pixels are
invalid (INVALID_INPUT); statuses are the shared codes of :mod:`s2cl.status`, the rule is the
sweep kernel's (``kernels/common/stages.mako``); a zero reference is refused with :class:`InputError`;
identical references
are allowed (a band design can make two minerals indistinguishable) and the first one wins
every tie, so results are deterministic and the confusion matrix shows the confusion.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass
from typing import Any

import numpy as np

from s2cl.cl.kernel_args import Arg, bind, signature
from s2cl.cl.runtime import Runtime
from s2cl.cl.templates import render
from s2cl.cl.vectypes import pad_pixels
from s2cl.errors import InputError
from s2cl.status import MAX_ABS_REFLECTANCE, Status


class SamStatus(enum.IntEnum):
    """Per-pixel outcome (``status``, uint8): the shared codes of :class:`s2cl.status.Status`."""

    CLASSIFIED = Status.OK
    UNCLASSIFIED = Status.UNCLASSIFIED  #: best angle above the threshold
    ZERO_VECTOR = Status.DEGENERATE  #: |pixel| = 0: no spectral direction
    INVALID_INPUT = Status.INVALID  #: NaN, inf or |rho| > max_abs


@dataclass
class SamResult:
    """Per-pixel SAM results, shape ``(n_pixels,)``.

    :param reference: index of the winning reference, -1 unless CLASSIFIED (int32).
    :param label: class of that reference, -1 unless CLASSIFIED (int32).
    :param angle: smallest spectral angle in radians (0 for ZERO_VECTOR / INVALID_INPUT).
    :param status: :class:`SamStatus` (uint8).
    """

    reference: np.ndarray
    label: np.ndarray
    angle: np.ndarray
    status: np.ndarray


#: the kernel's arguments (kernels/sam.cl.mako), in order
ARGS = (Arg("best", "out", "int"), Arg("angle", "out", "real"), Arg("status", "out", "uchar"),
        Arg("refl", "in", "real"), Arg("refs", "in", "real"), Arg("cos_min", "scalar", "real"),
        Arg("pitch", "scalar", "int"))


class SamClassifier:
    """Compiled SAM for one device, band count, reference count, precision and lane count.

    :param rt: the OpenCL runtime to run on.
    :param references: (n_refs, n_bands) reference spectra at sensor resolution (reflectance).
    :param reference_classes: class index (0..n_classes-1) of each reference; default: its own index.
    :param threshold_rad: maximum angle for a pixel to be classified; ``None``: no threshold.
    """

    def __init__(self, rt: Runtime, references: np.ndarray, reference_classes: np.ndarray | None = None, *,
                 threshold_rad: float | None = None, real_t: str = "float32", lanes: int | None = None,
                 max_abs: float = MAX_ABS_REFLECTANCE):
        self.rt = rt
        refs = np.asarray(references, dtype=np.float64)
        if refs.ndim != 2 or refs.shape[0] < 1 or refs.shape[1] < 1:
            raise InputError(f"must have shape (n_refs, n_bands), got {refs.shape}", key="references")
        if not np.all(np.isfinite(refs)):
            raise InputError("must be finite", key="references")
        norms = np.linalg.norm(refs, axis=1)
        if np.any(norms <= 1e-15):
            raise InputError(f"reference {int(np.argmin(norms))} is a zero vector: it has no spectral direction",
                             key="references")
        classes = np.arange(refs.shape[0]) if reference_classes is None else np.asarray(reference_classes)
        if classes.shape != (refs.shape[0],) or not np.issubdtype(classes.dtype, np.integer) or classes.min() < 0:
            raise InputError(f"must be {refs.shape[0]} non-negative class indices", key="reference_classes")
        if threshold_rad is not None and not 0.0 <= threshold_rad <= np.pi:
            raise InputError(f"must be in [0, pi] radians, got {threshold_rad}", key="threshold_rad")
        self.types = rt.types(real_t, lanes)
        self.n_refs, self.n_bands = refs.shape
        self.classes = classes.astype(np.int32)
        self.unit_refs = refs / norms[:, None]
        self.cos_min = -2.0 if threshold_rad is None else float(np.cos(threshold_rad))
        source = render("sam.cl.mako", T=self.types, n_bands=self.n_bands, n_refs=self.n_refs, max_abs=float(max_abs),
                        args=ARGS, signature=signature)
        self.kernel = rt.kernel(rt.build(source, template="sam.cl.mako"), "sam_classify")
        self._refs_d = rt.to_device(self.unit_refs.astype(self.types.dtype))

    def duplicate_references(self, tol_rad: float = 1e-6) -> list[tuple[int, int]]:
        """Pairs (i, j), i < j, of references within ``tol_rad`` of each other (j never wins)."""
        cos = np.clip(self.unit_refs @ self.unit_refs.T, -1.0, 1.0)
        i, j = np.nonzero(np.triu(np.arccos(cos) <= tol_rad, k=1))
        return list(zip(i.tolist(), j.tolist(), strict=True))

    def buffers(self, refl: np.ndarray) -> dict[str, Any]:
        """One launch's arguments, named as the kernel's: ``refl`` (n_bands, n_pixels) padded to whole
        lanes and uploaded, the outputs allocated, ``pitch`` the padded pixel count."""
        return self._buffers(refl)[0]

    def _buffers(self, refl: np.ndarray) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
        """:meth:`buffers` and the host arrays the outputs land in (:meth:`Runtime.output`)."""
        T, rt = self.types, self.rt
        host, pitch = pad_pixels(refl, T.lanes, T.dtype)
        arrays, v = {}, {}
        for name, dtype in (("best", np.int32), ("angle", T.dtype), ("status", np.uint8)):
            arrays[name], v[name] = rt.output((pitch,), dtype)
        v.update(refl=rt.upload_new(host), refs=self._refs_d, cos_min=self.cos_min, pitch=pitch)
        return v, arrays

    def enqueue(self, v: dict[str, Any]) -> None:
        """Queue the classification on the arguments ``v`` (:meth:`buffers`); returns at once."""
        items = v["pitch"] // self.types.lanes
        self.kernel(self.rt.queue, (items,), self.rt.local_size(self.kernel, items), *bind(ARGS, v, self.types))

    def classify(self, refl: np.ndarray) -> SamResult:
        """Classify every pixel of ``refl`` (n_bands, n_pixels)."""
        refl = np.asarray(refl)
        if refl.ndim != 2 or refl.shape[0] != self.n_bands:
            raise InputError(f"must have shape ({self.n_bands}, n_pixels), got {refl.shape}", key="reflectance")
        n, rt = refl.shape[1], self.rt
        v, arrays = self._buffers(refl)
        self.enqueue(v)
        out = {name: rt.result(v[name], array)[:n] for name, array in arrays.items()}
        best = out["best"]
        label = np.where(best >= 0, self.classes[np.maximum(best, 0)], -1).astype(np.int32)
        return SamResult(best, label, out["angle"], out["status"])


def confusion_matrix(true_class: np.ndarray, predicted: np.ndarray, n_classes: int) -> np.ndarray:
    """(n_classes, n_classes + 1) int64 counts: row = true class, column = predicted class, the last
    column = unclassified (predicted -1). Pixels whose true class is outside 0..n_classes-1 are refused."""
    t = np.asarray(true_class).ravel()
    p = np.asarray(predicted).ravel()
    if t.shape != p.shape:
        raise InputError(f"{t.size} true classes for {p.size} predictions", key="true_class")
    if t.size and (t.min() < 0 or t.max() >= n_classes):
        raise InputError(f"must be in 0..{n_classes - 1}", key="true_class")
    if p.size and (p.min() < -1 or p.max() >= n_classes):
        raise InputError(f"must be in -1..{n_classes - 1}", key="predicted")
    col = np.where(p < 0, n_classes, p)
    return np.bincount(t * (n_classes + 1) + col, minlength=n_classes * (n_classes + 1)).reshape(
        n_classes, n_classes + 1)


@dataclass(frozen=True)
class ClassificationScore:
    """Confusion matrix and the errors derived from it (fractions in [0, 1]).

    ``omission[i]`` = 1 - correct_i / pixels of class i (unclassified pixels count as omitted);
    ``mean_omission`` averages it over classes that have pixels (the paper's metric).
    """

    confusion: np.ndarray
    omission: np.ndarray
    mean_omission: float
    overall_accuracy: float
    frac_unclassified: float
    frac_invalid: float


def score_classification(true_class: np.ndarray, result: SamResult, n_classes: int) -> ClassificationScore:
    """Score a :class:`SamResult` against the true classes."""
    cm = confusion_matrix(true_class, result.label, n_classes)
    totals = cm.sum(axis=1)
    present = totals > 0
    omission = np.zeros(n_classes)
    omission[present] = 1.0 - np.diag(cm)[present] / totals[present]
    n = int(cm.sum())
    return ClassificationScore(
        confusion=cm,
        omission=omission,
        mean_omission=float(omission[present].mean()) if present.any() else 0.0,
        overall_accuracy=float(np.trace(cm[:, :n_classes]) / n) if n else 0.0,
        frac_unclassified=float(cm[:, -1].sum() / n) if n else 0.0,
        frac_invalid=float(np.mean(np.isin(result.status, (SamStatus.ZERO_VECTOR, SamStatus.INVALID_INPUT))))
        if n else 0.0,
    )
