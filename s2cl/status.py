"""Per-pixel status codes of every retrieval and pixel flags of the radiometric stage.

The one table is ``kernels/common/s2_status.clh`` (read it for what each code means); these enums
mirror it and ``tests/test_status.py`` checks that they agree. Every kernel, numpy twin and metric
uses these values: a pixel gets the same verdict in ``s2cl simulate`` and in a sweep.
"""

from __future__ import annotations

import enum


class Status(enum.IntEnum):
    """Outcome of a retrieval for one pixel (``status`` arrays, uint8)."""

    OK = 0
    ITERATION_LIMIT = 1
    DEGENERATE = 2
    INVALID = 3
    STALLED = 4
    UNCLASSIFIED = 5
    # the same codes under the names each retrieval uses
    CONVERGED = 0  #: IGRM
    CLASSIFIED = 0  #: SAM
    INVALID_INPUT = 3
    ZERO_VECTOR = 2  #: SAM: a pixel without direction


class PixelFlag(enum.IntFlag):
    """Bits of the radiometric stage's per-band pixel flags (``flags`` arrays, uint8)."""

    NONE = 0
    LOW = 1  #: radiance below Lmin: DN 0
    HIGH = 2  #: radiance above Lmax: saturated DN
    NODATA = 4  #: radiance NaN (an image cube's no-data pixels too): DN 0, calibrated radiance and reflectance NaN


#: |reflectance| above which a pixel is invalid input, in every retrieval (reflectance, not DN, is expected).
MAX_ABS_REFLECTANCE = 10.0

#: Statuses whose index is a fitted value (IGRM parameters exist; GVMI/SAM: the index is valid).
FITTED = (Status.OK, Status.STALLED, Status.ITERATION_LIMIT)

#: Names a scene may use in ``analysis.regress`` (which IGRM statuses enter the regression).
REGRESS_NAMES = {"converged": Status.OK, "stalled": Status.STALLED, "iteration_limit": Status.ITERATION_LIMIT}
