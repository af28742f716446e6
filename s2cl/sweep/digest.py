"""A sweep's results reduced in one streaming pass: what the ranking, the summary, the heatmaps and the
paper's tables need, in memory that does not grow with the number of configurations.

``results.parquet`` is read a batch of :data:`BATCH_ROWS` rows at a time (its row groups hold
:data:`s2cl.sweep.engine.ROW_GROUP_ROWS` rows). Per batch the digest keeps: counts (configurations, ranked,
underdetermined and their coinciding centres, configurations better than the reference), the best
:data:`TOP` rankable rows, and per band the best metric of each (centre, width) pair over the other bands
(a sorted array of the pairs seen: memory ∝ the band's variants, never centres × widths × configurations).
The heatmaps bin those pairs into at most :data:`HEATMAP_CENTRES` × :data:`HEATMAP_WIDTHS` cells
(:meth:`Digest.binned_grid`). A DataFrame in memory (tests, the Python API) goes through the same code as
one batch.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.retrieve.family import registry
from s2cl.retrieve.metric import metric_in

BATCH_ROWS = 65_536
TOP = 10
#: most centre rows and width columns a heatmap draws; beyond them consecutive values are grouped
HEATMAP_CENTRES, HEATMAP_WIDTHS = 60, 40
#: the types of what the digest holds per band variant (:class:`_PairBest`): the pair's key ``centre + 1j·width`` and
#: its best value
PAIR_KEY, PAIR_VALUE = np.dtype(np.complex128), np.dtype(np.float64)
#: copies of them held at once at most: the sorted pairs, those pending a merge, the merge's concatenation and its sort
PAIR_COPIES = 4
#: bytes the digest holds per band variant, from those types
BYTES_PER_VARIANT = PAIR_COPIES * (PAIR_KEY.itemsize + PAIR_VALUE.itemsize)
#: 8-byte copies of a batch's column the digest holds at once at most: the Parquet reader's decoded pages and the
#: blocks its allocator keeps, the Arrow batch, its DataFrame, the rankable rows and their sort
BATCH_COPIES = 14
BATCH_BYTES_PER_COLUMN = BATCH_COPIES * 8 * BATCH_ROWS


def metric_of(columns: list[str], meta: dict[str, str] | None = None) -> str:
    """The ranking metric of a results table: its analysis family's score column (``meta``: the table's metadata,
    whose ``analysis`` is the kind), else the metric column it holds."""
    family = registry().get((meta or {}).get("analysis", ""))
    if family is not None and family.score_column in columns:
        return family.score_column
    return metric_in(columns).score_column


def rankable_rows(df: Any, meta: dict[str, str]) -> Any:
    """The configurations a ranking may use: without the designs the analysis cannot fit (``underdetermined``,
    :mod:`s2cl.retrieve.design`) unless the sweep keeps them (``sweep.underdetermined``), and, in a search's
    results, only the designs scored on every pixel (``full_fidelity``, :mod:`s2cl.sweep.search`). Every
    ranking, heatmap and paper comparison goes through this one function."""
    if "full_fidelity" in df.columns:
        df = df[df["full_fidelity"].to_numpy(dtype=bool)]
    if "underdetermined" not in df.columns or meta.get("underdetermined", "exclude") == "keep":
        return df
    return df[~df["underdetermined"].to_numpy(dtype=bool)]


def bands_of(columns: Any) -> list[str]:
    return [c[: -len("_centre_nm")] for c in columns if c.endswith("_centre_nm")]


@dataclass
class _PairBest:
    """Best metric per (centre, width) pair of one band: sorted complex keys ``centre + 1j·width``; new pairs
    wait in ``pending`` and are merged when they outnumber the known ones (amortised: linear overall)."""

    keys: np.ndarray = field(default_factory=lambda: np.empty(0, PAIR_KEY))
    best: np.ndarray = field(default_factory=lambda: np.empty(0, PAIR_VALUE))
    pending: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    n_pending: int = 0

    def add(self, centre: np.ndarray, width: np.ndarray, value: np.ndarray) -> None:
        keys, inverse = np.unique(centre + 1j * width, return_inverse=True)
        best = np.full(keys.size, np.nan, PAIR_VALUE)
        np.fmin.at(best, inverse.ravel(), value)
        pos = np.searchsorted(self.keys, keys)
        found = pos < self.keys.size
        found[found] = self.keys[pos[found]] == keys[found]
        np.fmin.at(self.best, pos[found], best[found])
        if not found.all():
            self.pending.append((keys[~found], best[~found]))
            self.n_pending += int((~found).sum())
            if self.n_pending > self.keys.size:
                self.merge()

    def merge(self) -> None:
        if not self.pending:
            return
        keys = np.concatenate([self.keys, *(k for k, _ in self.pending)])
        best = np.concatenate([self.best, *(b for _, b in self.pending)])
        self.keys, inverse = np.unique(keys, return_inverse=True)
        self.best = np.full(self.keys.size, np.nan, PAIR_VALUE)
        np.fmin.at(self.best, inverse.ravel(), best)
        self.pending, self.n_pending = [], 0

    def value(self, centre: float, width: float) -> float:
        self.merge()
        i = int(np.searchsorted(self.keys, centre + 1j * width))
        return float(self.best[i]) if i < self.keys.size and self.keys[i] == centre + 1j * width else float("nan")


@dataclass
class Digest:
    """What a sweep's rows reduce to (see the module doc). Build with :meth:`of_file` or :meth:`of_frame`."""

    meta: dict[str, str]
    columns: list[str]
    reference: dict[str, Any] | None = None
    top_n: int = TOP
    match: list[list[float]] | None = None
    configurations: int = 0
    ranked: int = 0
    better: int = 0
    flagged: int = 0
    coincident: dict[str, int] = field(default_factory=dict)
    top: Any = None
    matches: Any = None
    pairs: dict[str, _PairBest] = field(default_factory=dict)
    source: Any = None
    #: the column ranked and gridded (default: the results' metric, :func:`metric_of`)
    metric_column: str | None = None

    @property
    def metric(self) -> str:
        return self.metric_column or metric_of(self.columns, self.meta)

    @property
    def bands(self) -> list[str]:
        return bands_of(self.columns)

    @classmethod
    def of_frame(cls, df: Any, meta: dict[str, str], **kwargs: Any) -> Digest:
        """The digest of a DataFrame of results (one batch)."""
        d = cls(dict(meta), [str(c) for c in df.columns], **kwargs)
        d.source = df
        d.add(df)
        return d

    @staticmethod
    def of_columns(path: str | Path) -> list[str]:
        """The column names of a results file (its schema only)."""
        import pyarrow.parquet as pq

        return list(pq.read_schema(path).names)

    @classmethod
    def of_file(cls, path: str | Path, meta: dict[str, str], **kwargs: Any) -> Digest:
        """The digest of ``results.parquet`` at ``path``, read :data:`BATCH_ROWS` rows at a time."""
        import pyarrow.parquet as pq

        columns = list(pq.read_schema(path).names)
        d = cls(dict(meta), columns, **kwargs)
        d.source = Path(path)
        for batch in _batches(path):
            d.add(batch)
        return d

    def rankable(self, df: Any) -> Any:
        """The rows a ranking may use (:func:`rankable_rows`)."""
        return rankable_rows(df, self.meta)

    def add(self, df: Any) -> None:
        """Reduce one batch of rows into the digest."""
        metric, bands = self.metric, self.bands
        self.configurations += len(df)
        if "underdetermined" in df.columns:
            self._add_flagged(df, bands)
        pool = self.rankable(df)
        self.ranked += len(pool)
        values = pool[metric].to_numpy(dtype=np.float64)
        if self.reference is not None and metric in self.reference:
            self.better += int(np.sum(values < self.reference[metric]))
        best = pool.sort_values([metric, "config"], na_position="last").head(self.top_n)
        self.top = best if self.top is None else _head(_concat([self.top, best]), metric, self.top_n)
        for b in bands:
            pairs = self.pairs.setdefault(b, _PairBest())
            pairs.add(pool[f"{b}_centre_nm"].to_numpy(np.float64), pool[f"{b}_width_nm"].to_numpy(np.float64),
                      values)
        if self.match is not None:
            hit = _match(pool, bands, self.match)
            if len(hit):
                self.matches = hit if self.matches is None else _concat([self.matches, hit])

    def _add_flagged(self, df: Any, bands: list[str]) -> None:
        flags = df["underdetermined"].to_numpy(dtype=bool)
        self.flagged += int(flags.sum())
        if not flags.any():
            return
        for i, a in enumerate(bands):
            ca = df[f"{a}_centre_nm"].to_numpy()[flags]
            for b in bands[i + 1:]:
                same = int(np.sum(np.abs(ca - df[f"{b}_centre_nm"].to_numpy()[flags]) < 1e-6))
                if same:
                    self.coincident[f"{a}={b}"] = self.coincident.get(f"{a}={b}", 0) + same

    def count_below(self, value: float) -> int:
        """Rankable configurations whose metric is below ``value`` (a second pass over a file)."""
        frames = [self.source] if not isinstance(self.source, Path) else _batches(self.source)
        return sum(int(np.sum(self.rankable(f)[self.metric].to_numpy(np.float64) < value)) for f in frames)

    def variants(self, band: str) -> int:
        """Distinct (centre, width) pairs of ``band`` among the rankable configurations."""
        pairs = self.pairs.get(band)
        if pairs is None:
            return 0
        pairs.merge()
        return int(pairs.keys.size)

    def value(self, band: str, centre: float, width: float) -> float:
        """Best metric over the other bands at ``band`` = (centre, width); NaN when no configuration has it."""
        return self.pairs[band].value(centre, width) if band in self.pairs else float("nan")

    def binned_grid(self, band: str, max_centres: int = HEATMAP_CENTRES, max_widths: int = HEATMAP_WIDTHS
                    ) -> tuple[list[str], list[str], np.ndarray, tuple[int, int]]:
        """The centre × width table of ``band`` in at most ``max_centres`` × ``max_widths`` cells.

        Rule: with ``n`` distinct centres, consecutive centres are grouped ``g = ceil(n / max_centres)`` to a
        row (the same for widths); a cell holds the best value of the pairs in its group (NaN where none is a
        variant). Labels name each group (``640`` or ``640–645``). Returns (centre labels, width labels,
        values ``(rows, columns)``, (centres per row, widths per column)).
        """
        pairs = self.pairs[band]
        pairs.merge()
        c, w = pairs.keys.real, pairs.keys.imag
        centres, ci = np.unique(c, return_inverse=True)
        widths, wi = np.unique(w, return_inverse=True)
        gc, gw = -(-centres.size // max_centres), -(-widths.size // max_widths)
        values = np.full((-(-centres.size // gc), -(-widths.size // gw)), np.nan)
        np.fmin.at(values, (ci.ravel() // gc, wi.ravel() // gw), pairs.best)
        return _labels(centres, gc), _labels(widths, gw), values, (gc, gw)


    def binned_cells(self, band: str, pairs: list[tuple[float, float]], max_centres: int = HEATMAP_CENTRES,
                     max_widths: int = HEATMAP_WIDTHS) -> np.ndarray:
        """Boolean mask of :meth:`binned_grid`'s cells of ``band`` that hold one of the (centre, width)
        ``pairs`` (nm); pairs that are not variants of ``band`` mark nothing."""
        grid = self.pairs[band]
        grid.merge()
        centres, widths = np.unique(grid.keys.real), np.unique(grid.keys.imag)
        gc, gw = -(-centres.size // max_centres), -(-widths.size // max_widths)
        mask = np.zeros((-(-centres.size // gc), -(-widths.size // gw)), bool)
        for c, w in pairs:
            i, j = int(np.searchsorted(centres, c)), int(np.searchsorted(widths, w))
            if i < centres.size and j < widths.size and centres[i] == c and widths[j] == w:
                mask[i // gc, j // gw] = True
        return mask


def _labels(values: np.ndarray, group: int) -> list[str]:
    out = []
    for a in range(0, values.size, group):
        first, last = values[a], values[min(a + group, values.size) - 1]
        out.append(f"{first:g}" if first == last else f"{first:g}–{last:g}")
    return out


def results_batches(path: str | Path) -> Iterator[Any]:
    """The results table at ``path`` as DataFrames of :data:`BATCH_ROWS` rows each, in order (what the digest
    reads; memory: one batch)."""
    return _batches(path)


def _batches(path: str | Path) -> Iterator[Any]:
    import pyarrow.parquet as pq

    # pre_buffer=False: with it, pyarrow buffers every row group of the file ahead of the batches (the digest's memory
    # grew with the configurations: 0.5 GB for 1.6 M rows of 26 columns)
    with pq.ParquetFile(path, pre_buffer=False) as f:
        for batch in f.iter_batches(batch_size=BATCH_ROWS):
            yield batch.to_pandas()


def _concat(frames: list[Any]) -> Any:
    import pandas as pd

    return pd.concat(frames, ignore_index=True)


def _head(df: Any, metric: str, n: int) -> Any:
    return df.sort_values([metric, "config"], na_position="last").head(n).reset_index(drop=True)


def _match(df: Any, bands: list[str], shape: list[list[float]], tol_nm: float = 0.5) -> Any:
    """Rows of ``df`` whose bands equal ``shape`` (the paper prints 832 for 832.5: tolerance 0.5 nm)."""
    mask = np.ones(len(df), bool)
    for b, (c, w) in zip(bands, shape, strict=True):
        mask &= (np.abs(df[f"{b}_centre_nm"].to_numpy() - c) <= tol_nm) & (df[f"{b}_width_nm"].to_numpy() == w)
    return df[mask]
