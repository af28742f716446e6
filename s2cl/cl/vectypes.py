"""OpenCL type names for kernels that process ``lanes`` pixels per work-item.

Templates that use explicit vector lanes (``float8`` on PoCL CPUs, scalar ``float`` on GPUs)
receive one :class:`VecTypes` and write every type and literal through it, so that the same
template renders float32 and float64, scalar and vector code. No typedefs are emitted (a fused
kernel may splice several such templates together).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from s2cl.errors import InputError

REAL_TYPES = {"float32": "float", "float64": "double"}
VALID_LANES = (1, 2, 4, 8, 16)


@dataclass(frozen=True)
class VecTypes:
    """Type names for one (precision, lanes) pair.

    :param real_t: ``"float32"`` or ``"float64"``.
    :param lanes: pixels per work-item, one of 1, 2, 4, 8, 16.
    """

    real_t: str = "float32"
    lanes: int = 8

    def __post_init__(self) -> None:
        if self.real_t not in REAL_TYPES:
            raise InputError(f"must be one of {sorted(REAL_TYPES)}, got {self.real_t!r}", key="real_t")
        if self.lanes not in VALID_LANES:
            raise InputError(f"must be one of {VALID_LANES}, got {self.lanes!r}", key="lanes")

    @property
    def double(self) -> bool:
        return self.real_t == "float64"

    @property
    def dtype(self) -> np.dtype:
        """numpy dtype of the reals."""
        return np.dtype(self.real_t)

    @property
    def R(self) -> str:
        """Scalar real type: ``float`` or ``double``."""
        return REAL_TYPES[self.real_t]

    def vec(self, base: str) -> str:
        """``base`` with the lane count appended (``int8``), or ``base`` itself for one lane."""
        return base if self.lanes == 1 else f"{base}{self.lanes}"

    @property
    def V(self) -> str:
        """Real type holding one value per lane (``float8``; ``float`` when lanes = 1)."""
        return self.vec(self.R)

    @property
    def M(self) -> str:
        """Mask/integer type of the result of comparing two ``V`` values.

        Vector comparisons give -1 (all bits set) for true and have integers as wide as the
        reals (``int8`` for ``float8``, ``long8`` for ``double8``); scalar comparisons give
        an ``int`` 1 or 0. Masks are combined with ``&``, ``|`` and ``!`` only, which behave
        the same in both cases, and consumed by the ternary operator.
        """
        if self.lanes == 1:
            return "int"
        return self.vec("long" if self.double else "int")

    @property
    def IB(self) -> str:
        """Integer type with the bit width of ``V`` (for ``as_*`` reinterpretation)."""
        return self.vec("long" if self.double else "int")

    @property
    def suffix(self) -> str:
        """Name suffix that makes helpers of different types distinct (``f8``, ``d1``)."""
        return ("d" if self.double else "f") + str(self.lanes)

    def lit(self, value: float) -> str:
        """A real literal of the scalar type: shortest text that rounds to ``value`` in that
        precision, with an ``f`` suffix for float (no double constant in float builds)."""
        if not np.isfinite(value):
            raise InputError(f"literal must be finite, got {value}")
        if self.double:
            return np.format_float_scientific(np.float64(value), unique=True, trim="0")
        return np.format_float_scientific(np.float32(value), unique=True, trim="0") + "f"

    def vlit(self, value: float) -> str:
        """The literal broadcast to ``V``."""
        return f"(({self.V}){self.lit(value)})"

    def convert(self, target_base: str) -> str:
        """Name of the conversion function from ``M`` to ``target_base`` with lanes (``convert_uchar8``)."""
        return f"convert_{self.vec(target_base)}"


def pad_pixels(rows: np.ndarray, lanes: int, dtype: np.dtype, fill: float = 0.0) -> tuple[np.ndarray, int]:
    """``rows`` (n_rows, n_pixels) as a C-contiguous ``dtype`` array whose row length (the pitch)
    is a multiple of ``lanes`` (at least ``lanes``), padded with ``fill``; no copy when it already is.
    Returns (array, pitch)."""
    n = rows.shape[1]
    pitch = max(-(-n // lanes) * lanes, lanes)
    if pitch == n and rows.dtype == dtype and rows.flags.c_contiguous:
        return rows, pitch
    host = np.full((rows.shape[0], pitch), fill, dtype=dtype)
    host[:, :n] = rows
    return host, pitch
