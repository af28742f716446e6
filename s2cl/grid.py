"""The spectral grid of high-resolution spectra (wavelengths in nm)."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from s2cl.errors import InputError

#: most wavelengths a grid may have (0.021 nm over 400–2500 nm; every library spectrum is held on it)
MAX_SAMPLES = 100_000


@dataclass(frozen=True)
class SpectralGrid:
    """Regular wavelength grid, ``start_nm`` to ``stop_nm`` inclusive, step ``step_nm``.

    The default 400–2500 nm at 1 nm matches the paper's input spectra. A coarser step is an
    accuracy/time knob: it is never chosen silently.
    """

    start_nm: float = 400.0
    stop_nm: float = 2500.0
    step_nm: float = 1.0

    def __post_init__(self) -> None:
        for name in ("start_nm", "stop_nm", "step_nm"):
            value = getattr(self, name)
            if not np.isfinite(value):
                raise InputError(f"must be finite, got {value}", key=f"grid.{name}")
        if self.step_nm <= 0:
            raise InputError(f"must be > 0 nm, got {self.step_nm}", key="grid.step_nm")
        if self.stop_nm <= self.start_nm:
            raise InputError(
                f"must be > grid.start_nm = {self.start_nm}, got {self.stop_nm}", key="grid.stop_nm"
            )
        n = (self.stop_nm - self.start_nm) / self.step_nm
        if n > MAX_SAMPLES:
            finest = (self.stop_nm - self.start_nm) / MAX_SAMPLES
            raise InputError(f"{self.step_nm:g} nm gives {n:,.0f} wavelengths over {self.start_nm:g}–{self.stop_nm:g} "
                             f"nm (at most {MAX_SAMPLES:,}: a step >= {finest:.2g} nm)", key="grid.step_nm")
        if abs(n - round(n)) > 1e-6:
            raise InputError(
                f"range {self.start_nm}–{self.stop_nm} nm is not a whole number of {self.step_nm} nm steps",
                key="grid.step_nm",
            )

    @cached_property
    def wavelengths(self) -> np.ndarray:
        """Wavelengths in nm, float64, shape ``(n,)``."""
        n = round((self.stop_nm - self.start_nm) / self.step_nm) + 1
        return self.start_nm + self.step_nm * np.arange(n, dtype=np.float64)

    @property
    def size(self) -> int:
        """Number of wavelengths."""
        return int(self.wavelengths.size)

    def index(self, wavelength_nm: float) -> int:
        """Index of the grid wavelength nearest to ``wavelength_nm``, clipped into the grid."""
        i = round((wavelength_nm - self.start_nm) / self.step_nm)
        return int(min(max(i, 0), self.size - 1))

    def covers(self, lo_nm: float, hi_nm: float) -> bool:
        """Whether [lo_nm, hi_nm] lies inside the grid."""
        return self.start_nm <= lo_nm and hi_nm <= self.stop_nm

    def describe(self) -> str:
        return f"{self.start_nm:g}–{self.stop_nm:g} nm, step {self.step_nm:g} nm ({self.size} wavelengths)"


DEFAULT_GRID = SpectralGrid()


def check_wavelengths(wavelengths_nm: np.ndarray, *, source: str | None = None, key: str = "wavelength") -> np.ndarray:
    """Validate a user wavelength axis: 1-D, finite, > 0, strictly increasing. Returns float64."""
    w = np.asarray(wavelengths_nm, dtype=np.float64)
    if w.ndim != 1 or w.size < 2:
        raise InputError(f"needs a 1-D axis of at least 2 wavelengths, got shape {w.shape}", source=source, key=key)
    if not np.all(np.isfinite(w)):
        bad = int(np.flatnonzero(~np.isfinite(w))[0])
        raise InputError(f"holds a non-finite value at position {bad}", source=source, key=key)
    if np.any(w <= 0):
        bad = int(np.flatnonzero(w <= 0)[0])
        raise InputError(f"wavelengths must be > 0, got {w[bad]:g} at position {bad}", source=source, key=key)
    steps = np.diff(w)
    if np.any(steps <= 0):
        bad = int(np.flatnonzero(steps <= 0)[0])
        raise InputError(
            f"must be strictly increasing; position {bad + 1} ({w[bad + 1]:g} nm) follows {w[bad]:g} nm",
            source=source,
            key=key,
        )
    return w
