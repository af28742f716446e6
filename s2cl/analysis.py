"""The analysis that scores a band design: IGRM red-edge index, GVMI, or SAM classes.

Per-pixel status codes shared by every analysis (uint8):
``0`` converged / valid, ``1`` IGRM iteration limit, ``2`` degenerate (IGRM: flat or singular fit;
SAM: unclassified, every angle above the threshold), ``3`` invalid input (NaN/inf reflectance,
zero vector, GVMI denominator <= 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .errors import InputError

OK, ITERATION_LIMIT, DEGENERATE, INVALID = 0, 1, 2, 3


@dataclass(frozen=True)
class AnalysisSettings:
    """What to compute from the band reflectances of each pixel.

    :param kind: ``"igrm"`` (index: inflection wavelength λp in nm), ``"gvmi"`` (index: GVMI) or
        ``"sam"`` (class of each pixel).
    :param parameter: library parameter regressed on the index (``cab``, ``ewt``); igrm/gvmi.
    :param nir_slot, swir_slot: gvmi: band slots of the NIR and SWIR bands.
    :param angle_threshold_deg: sam: pixels whose smallest angle exceeds it are unclassified.
    :param igrm: IGRM fit settings (keys of ``s2cl.igrm.IgrmSettings``).
    """

    kind: str
    parameter: str | None = None
    nir_slot: int = 0
    swir_slot: int = 1
    angle_threshold_deg: float | None = None
    igrm: tuple[tuple[str, Any], ...] = field(default_factory=tuple)

    @property
    def regression(self) -> bool:
        return self.kind in ("igrm", "gvmi")

    @classmethod
    def from_scene(cls, scene: Any, bands: list[str]) -> AnalysisSettings:
        """From the scene's [analysis] section; ``bands`` are the band slots in order."""
        a = scene.spec.analysis
        if a is None:
            raise InputError("the scene has no [analysis] section", source=scene.source, key="analysis")
        lower = [b.lower() for b in bands]

        def slot(name: str | None, key: str) -> int:
            if name is None:
                raise InputError("gvmi needs nir and swir band names", source=scene.source, key=f"analysis.{key}")
            if name.lower() not in lower:
                raise InputError(f"band {name!r} is not among the bands {', '.join(bands)}", source=scene.source,
                                 key=f"analysis.{key}")
            return lower.index(name.lower())

        if a.kind in ("igrm", "gvmi") and not a.parameter:
            raise InputError(f"{a.kind} needs the library parameter to regress (e.g. 'cab', 'ewt')",
                             source=scene.source, key="analysis.parameter")
        if a.kind == "igrm" and len(bands) < 4:
            raise InputError(f"IGRM needs at least 4 bands, got {len(bands)}", source=scene.source, key="analysis")
        if a.kind == "gvmi":
            return cls("gvmi", a.parameter, nir_slot=slot(a.nir, "nir"), swir_slot=slot(a.swir, "swir"))
        if a.kind == "sam":
            return cls("sam", angle_threshold_deg=a.angle_threshold_deg)
        return cls("igrm", a.parameter, igrm=tuple(sorted(a.igrm.items())))


def gvmi(nir: np.ndarray, swir: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """GVMI (Segl et al. 2012 eq. 3) and status: ((NIR+0.1) − (SWIR+0.02)) / ((NIR+0.1) + (SWIR+0.02))."""
    num = (nir + 0.1) - (swir + 0.02)
    den = (nir + 0.1) + (swir + 0.02)
    ok = np.isfinite(num) & np.isfinite(den) & (den > 0)
    index = np.where(ok, num / np.where(ok, den, 1.0), 0.0)
    return index, np.where(ok, OK, INVALID).astype(np.uint8)


def sam_classify(pixels: np.ndarray, references: np.ndarray, threshold_deg: float | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spectral angle mapper.

    :param pixels: ``(..., n_bands)`` reflectance.
    :param references: ``(..., n_classes, n_bands)`` class references (broadcast against pixels).
    :returns: class index (``n_classes`` = unclassified), smallest angle (rad), status.
    """
    n_classes = references.shape[-2]
    p = pixels[..., None, :]
    dot = (p * references).sum(-1)
    norms = np.sqrt((p * p).sum(-1)) * np.sqrt((references * references).sum(-1))
    finite = np.all(np.isfinite(pixels), axis=-1)
    ok_norm = norms > 0
    cosine = np.where(ok_norm, dot / np.where(ok_norm, norms, 1.0), -2.0)
    best = np.argmax(cosine, axis=-1)
    angle = np.arccos(np.clip(np.take_along_axis(cosine, best[..., None], -1)[..., 0], -1.0, 1.0))
    status = np.full(best.shape, OK, np.uint8)
    invalid = ~finite | ~np.any(ok_norm, axis=-1) | (np.sqrt((pixels * pixels).sum(-1)) == 0)
    if threshold_deg is not None:
        status[angle > np.deg2rad(threshold_deg)] = DEGENERATE
    status[invalid] = INVALID
    best = np.where(status == OK, best, n_classes)
    return best.astype(np.int64), np.where(invalid, 0.0, angle), status
