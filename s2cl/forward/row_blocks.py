"""Row blocks of an image cube: which input rows each block simulates and which it reads around them (the halo of
the spatial filters, :func:`s2cl.forward.reach.cube_halo`), so that a block's output rows equal those of the whole
image simulated at once (tested)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: scipy.ndimage.gaussian_filter's default truncation (standard deviations): the kernel's radius
GAUSSIAN_TRUNCATE = 4.0


def gaussian_radius(sigma: float) -> int:
    """Rows a Gaussian filter of ``sigma`` (pixels) reaches on each side, as scipy.ndimage sizes its kernel."""
    return int(GAUSSIAN_TRUNCATE * float(sigma) + 0.5)


@dataclass(frozen=True)
class RowBlock:
    """Input rows ``start … stop-1`` simulated, read with their halo ``read_start … read_stop-1``."""

    start: int
    stop: int
    read_start: int
    read_stop: int

    def output_rows(self, factor: int) -> slice:
        """The rows of a band of ``factor`` input pixels per output pixel that this block yields (a block starts
        on a multiple of every factor; trailing input rows that fill no output row yield none)."""
        return slice(self.start // factor, self.stop // factor)


def row_blocks(rows: int, factors: list[int], block_rows: int | None, halo: int) -> list[RowBlock]:
    """Blocks of about ``block_rows`` input rows (all rows when None), each a multiple of every band's ``factors``
    (the last takes the rest), read with ``halo`` rows on each side where the image has them."""
    unit = math.lcm(*factors) if factors else 1
    step = rows if not block_rows else max(unit, (block_rows // unit) * unit)
    out = []
    for start in range(0, rows, max(step, 1)):
        stop = rows if start + step >= rows else start + step
        out.append(RowBlock(start, stop, max(0, start - halo), min(rows, stop + halo)))
        if stop == rows:
            break
    return out


def box_mean(image: np.ndarray, factor: int) -> np.ndarray:
    """Mean of ``factor × factor`` blocks (float64 sums), in ``image``'s dtype; trailing partial blocks dropped."""
    if factor == 1:
        return image
    rows, cols = (image.shape[0] // factor) * factor, (image.shape[1] // factor) * factor
    blocks = image[:rows, :cols].reshape(rows // factor, factor, cols // factor, factor)
    return blocks.mean(axis=(1, 3), dtype=np.float64).astype(image.dtype)
