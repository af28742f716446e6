"""A list of designs as sweep tables, on a nested subset of the noise copies.

A search scores designs that are no product space (the best fraction of the last rung, a neighbourhood): it
gathers each design's variant rows from the space's separable tables into tables of its own (``diagonal``:
configuration ``c`` takes row ``c`` of every slot), so that the fused sweep kernel scores them as it scores
any chunk. Fidelity is the number of noise copies per spectrum: copies ``0 … k-1`` of every spectrum, each
pixel with the deviate it has in the full sweep (``z`` is keyed by pixel and band, never by configuration), so
a design's score at ``k`` copies is the same whenever and with whatever it is scored, and at all copies it is
the exhaustive sweep's score of that design.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from s2cl.sweep.tables import SweepTables


def copy_pixels(t: SweepTables, copies: int) -> np.ndarray:
    """Pixel numbers of the full tables that copies ``0 … copies-1`` of every spectrum hold (spectrum-major,
    as the kernel lays pixels out: pixel ``p`` is copy ``p % copies`` of spectrum ``p // copies``)."""
    if not 1 <= copies <= t.copies:
        raise ValueError(f"copies must be 1 to {t.copies}, got {copies}")
    return (np.arange(t.n_spectra)[:, None] * t.copies + np.arange(copies)[None, :]).ravel()


def design_tables(t: SweepTables, designs: np.ndarray, copies: int, rows: int | None = None) -> SweepTables:
    """Tables of ``designs`` (variant index per slot, ``(n, n_slots)``) on ``copies`` noise copies.

    :param rows: rows per slot (at least ``n``; the last design repeats): one row count per fidelity keeps the
        kernel's source, and so its build, the same for every batch.
    """
    designs = np.asarray(designs, dtype=np.int64)
    n = designs.shape[0]
    rows = n if rows is None else rows
    if n < 1 or rows < n or designs.shape[1] != t.n_slots:
        raise ValueError(f"designs must be (1…{rows}, {t.n_slots}), got {designs.shape}")
    pad = np.concatenate([designs, np.repeat(designs[-1:], rows - n, axis=0)])
    pix = copy_pixels(t, copies)

    def take(arrays: tuple[np.ndarray, ...]) -> tuple[np.ndarray, ...]:
        return tuple(np.ascontiguousarray(a[pad[:, k]]) for k, a in enumerate(arrays))

    return replace(t, counts=(rows,) * t.n_slots, centre=take(t.centre), width=take(t.width),
                   radiance=take(t.radiance), values={**t.values, **{n: take(t.values[n]) for n in t.per_row()}},
                   references=take(t.references) if t.references else (), copies=copies,
                   z=np.ascontiguousarray(t.z[:, pix]), target=np.ascontiguousarray(t.target[pix]), diagonal=True)


def config_tables(t: SweepTables, configs: np.ndarray, rows: int | None = None) -> SweepTables:
    """Tables of configurations ``configs`` of ``t`` on every copy (row ``i``: configuration ``configs[i]``, the
    same score; ``rows``: as :func:`design_tables`): how given designs are scored (:mod:`s2cl.sweep.designs`),
    whatever their numbers, those beyond the kernel's 32-bit configuration numbers included."""
    flat = np.asarray(configs, dtype=np.int64).ravel()
    designs = np.empty((flat.size, t.n_slots), dtype=np.int64)
    for k in range(t.n_slots - 1, -1, -1):
        flat, designs[:, k] = np.divmod(flat, t.counts[k])
    return design_tables(t, designs, t.copies, rows)
