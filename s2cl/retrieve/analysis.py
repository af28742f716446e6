"""The analysis that scores a band design, as settings read from a scene: IGRM red-edge index, a
normalised-difference index (GVMI, ...: :mod:`s2cl.retrieve.indices`), a formula, or SAM classes. What each kind
means is its family's (:mod:`s2cl.retrieve.family`).

Per-pixel statuses are the shared codes of :mod:`s2cl.status` (``kernels/common/s2_status.clh``);
which designs can be analysed at all is :mod:`s2cl.retrieve.design`'s rule.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from s2cl.errors import InputError, token
from s2cl.libraries.library import SpectralLibrary
from s2cl.retrieve.family import AnalysisSettings

__all__ = ["AnalysisSettings", "analysis_targets"]


def analysis_targets(lib: SpectralLibrary, analysis: AnalysisSettings, classes: Sequence[str] | None = None
                     ) -> tuple[SpectralLibrary, np.ndarray, tuple[str, ...]]:
    """The library (restricted to the SAM classes), the per-spectrum target and the class names; ``classes``: the
    scene's ``analysis.classes`` (None or empty: every group of the library). Errors name the key."""
    if analysis.family.metric.classifies:
        wanted = list(classes or sorted(set(lib.groups)))
        twice = sorted({c for c in wanted if wanted.count(c) > 1})
        if twice:
            raise InputError(f"lists class(es) {', '.join(map(token, twice))} more than once; SAM needs at least two "
                             "different classes", key="analysis.classes")
        missing = [c for c in wanted if c not in lib.groups]
        if missing:
            raise InputError(f"no spectra of class(es) {', '.join(map(token, missing))}; library groups: "
                             f"{', '.join(sorted(set(lib.groups)))}", key="analysis.classes")
        if len(wanted) < 2:
            raise InputError("SAM needs at least two classes", key="analysis.classes")
        keep = [i for i, g in enumerate(lib.groups) if g in wanted]
        lib = lib.subset(keep)
        return lib, np.array([wanted.index(g) for g in lib.groups], dtype=np.float64), tuple(wanted)
    param = analysis.parameter
    if param not in lib.params:
        raise InputError(f"library has no parameter {token(param)}; it has {', '.join(sorted(lib.params)) or 'none'}",
                         key="analysis.parameter")
    return lib, np.asarray(lib.params[param], dtype=np.float64), ()
