"""The joint results of a sweep with several applications: one row per design of the shared [sweep] space, filled
by lookup from each application's own sweep (its results over its own sub-space, :mod:`s2cl.app.applications`).

A design's row holds its band centres and widths, every column of the first application's row (so the ranking,
the heatmaps and the reference row read it as a single-application sweep's), and one score column per application
(``<name>_<score column>``, float64; NaN where the application cannot fit the design and its sweep leaves such
designs out of the ranking). The table is written in chunks, resumably, with the sweep engine's folder machinery
(manifest, ``chunks/part-*.parquet``, :func:`s2cl.sweep.folder.merge_chunks`); the applications' columns are read
from memory (an application's own space is small) or, beyond :data:`IN_MEMORY_BYTES`, from memory-mapped files (in
``applications/.lookup/`` while the table is written), so memory does not grow with the joint space (one chunk at a
time).
"""

from __future__ import annotations

import datetime as dt
import hashlib
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.resources import code_fingerprint
from s2cl.sweep.digest import Digest, results_batches
from s2cl.sweep.engine import APPLICATIONS
from s2cl.sweep.folder import RESULTS, chunk_done, merge_chunks, write_chunk
from s2cl.version import __version__

#: designs per chunk of the joint table (the rows of one results row group: memory ∝ it, not the space)
JOINT_CHUNK = 65_536
#: an application's looked-up columns are held in memory up to this size (bytes), memory-mapped from disk beyond
IN_MEMORY_BYTES = 64 * 2**20


@dataclass(frozen=True)
class JointApplication:
    """What the joint table takes from one application: its ``name``, its results ``column`` in the joint table,
    its results' ``score`` column, whether its whole row is copied (``whole_row``: the first application's, every
    column but its configuration number and band shapes), ``slots``
    (per slot of its own space, the joint slot it reads, or None) and ``counts`` (its variants per slot), whether
    its underdetermined designs score NaN (``exclude``) and its sweep's ``fingerprint``."""

    name: str
    column: str
    score: str
    whole_row: bool
    slots: tuple[int | None, ...]
    counts: tuple[int, ...]
    exclude: bool
    fingerprint: str

    @property
    def n_configs(self) -> int:
        """Configurations of its own sweep."""
        return int(np.prod(self.counts, dtype=np.int64))

    def configs_of(self, joint: np.ndarray) -> np.ndarray:
        """Its configuration numbers of the joint designs with variant indices ``joint`` ``(n, joint slots)``
        (:func:`indices_of`)."""
        out = np.zeros(joint.shape[0], dtype=np.int64)
        for slot, count in zip(self.slots, self.counts, strict=True):
            out = out * count + (joint[:, slot] if slot is not None else 0)
        return out


@dataclass(frozen=True, eq=False)
class JointJob:
    """The joint table of a multi-application sweep: the joint space's bands, variants per band (``counts``) and
    their centres and widths (nm), the applications (the first one's row is the table's), the chunk, the scene's
    name and the results' schema metadata."""

    bands: tuple[str, ...]
    counts: tuple[int, ...]
    centre: tuple[np.ndarray, ...]
    width: tuple[np.ndarray, ...]
    apps: tuple[JointApplication, ...]
    scene_name: str
    meta: dict[bytes, bytes]
    chunk: int = JOINT_CHUNK

    @property
    def n_slots(self) -> int:
        return len(self.bands)

    @property
    def n_configs(self) -> int:
        return int(np.prod(self.counts, dtype=object))

    def chunks(self) -> list[tuple[int, int]]:
        return [(lo, min(lo + self.chunk, self.n_configs)) for lo in range(0, self.n_configs, self.chunk)]

    def fingerprint(self) -> str:
        """sha256 of the joint layout and of every application's sweep: the same fingerprint, the same table."""
        h = hashlib.sha256()
        h.update(repr((self.bands, self.counts, __version__, code_fingerprint())).encode())
        for a in (*self.centre, *self.width):
            h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
        for app in self.apps:
            h.update(repr(app).encode())
        return h.hexdigest()

    def manifest(self) -> dict[str, Any]:
        """The joint folder's manifest (:func:`s2cl.sweep.engine.prepare_folder`)."""
        return {"fingerprint": self.fingerprint(), "code": code_fingerprint(), "scene": self.scene_name,
                "s2cl_version": __version__, "configurations": self.n_configs, "chunk": self.chunk,
                "bands": list(self.bands), "counts": list(self.counts),
                "applications": [a.name for a in self.apps],
                "created": dt.datetime.now(dt.UTC).isoformat(timespec="seconds")}

    def rows(self, lo: int, hi: int, lookups: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
        """Rows of designs ``lo … hi-1``: config, band centres and widths, the first application's columns, each
        application's score column; ``lookups``: per application, the columns it copies and its score (and
        ``underdetermined``) by configuration number."""
        idx = indices_of(self.counts, np.arange(lo, hi, dtype=np.int64))
        rows: dict[str, np.ndarray] = {"config": np.arange(lo, hi, dtype=np.int64)}
        for k, b in enumerate(self.bands):
            rows[f"{b}_centre_nm"] = self.centre[k][idx[:, k]]
            rows[f"{b}_width_nm"] = self.width[k][idx[:, k]]
        for app, look in zip(self.apps, lookups, strict=True):
            configs = app.configs_of(idx)
            for c in look if app.whole_row else ():
                rows[c] = np.asarray(look[c][configs])
            score = np.asarray(look[app.score][configs], dtype=np.float64)
            if app.exclude:
                score = np.where(np.asarray(look["underdetermined"][configs], dtype=bool), np.nan, score)
            rows[app.column] = score
        return rows


def lookup_columns(results: Path, n: int, columns: list[str], folder: Path) -> dict[str, np.ndarray]:
    """``columns`` of the results table ``results`` (``n`` rows) by configuration number: in memory when they take
    at most :data:`IN_MEMORY_BYTES`, else as read-only memory-mapped arrays in ``folder`` (filled a batch at a time:
    memory bounded whatever the table's size)."""
    in_memory = n * len(columns) * 8 <= IN_MEMORY_BYTES
    if not in_memory:
        folder.mkdir(parents=True, exist_ok=True)
    maps: dict[str, np.ndarray] = {}
    for batch in results_batches(results):
        configs = batch["config"].to_numpy()
        for c in columns:
            values = batch[c].to_numpy()
            if c not in maps:
                maps[c] = np.empty(n, dtype=values.dtype) if in_memory else \
                    np.lib.format.open_memmap(folder / f"{c}.npy", mode="w+", dtype=values.dtype, shape=(n,))
            maps[c][configs] = values
    if in_memory:
        return maps
    for m in maps.values():
        m.flush()  # type: ignore[attr-defined]
    del maps
    return {c: np.load(folder / f"{c}.npy", mmap_mode="r") for c in columns}


def row_columns(results: Path) -> list[str]:
    """The columns of a sweep's results that a joint row copies: all but ``config`` and the band shapes."""
    return [c for c in Digest.of_columns(results) if c != "config" and not c.endswith(("_centre_nm", "_width_nm"))]


def indices_of(counts: tuple[int, ...], configs: np.ndarray) -> np.ndarray:
    """Variant index per slot ``(len(configs), len(counts))`` of the configuration numbers ``configs`` of a space
    with ``counts`` variants per slot (mixed radix, last slot fastest, as :func:`s2cl.sweep.raw.variant_indices`
    numbers a range of them)."""
    flat = np.asarray(configs, dtype=np.int64).copy()
    out = np.empty((flat.size, len(counts)), dtype=np.int64)
    for k in range(len(counts) - 1, -1, -1):
        flat, out[:, k] = np.divmod(flat, counts[k])
    return out


def run_joint(job: JointJob, out: Path, results: list[Path]) -> Path:
    """Write (or resume) the joint table of ``job`` into ``out`` (its manifest already written:
    :func:`s2cl.sweep.engine.prepare_folder`) from the applications' ``results`` (their ``results.parquet``, in
    the order of ``job.apps``); the path of ``results.parquet``."""
    todo = [(lo, hi) for lo, hi in job.chunks() if not chunk_done(out, lo, hi)]
    if todo:
        scratch = out / APPLICATIONS / ".lookup"
        try:
            lookups = []
            for i, (app, path) in enumerate(zip(job.apps, results, strict=True)):
                wanted = row_columns(path) if app.whole_row else [app.score, "underdetermined"]
                lookups.append(lookup_columns(path, app.n_configs, wanted, scratch / str(i)))
            for lo, hi in todo:
                write_chunk(out, lo, job.rows(lo, hi, lookups))
            del lookups
        finally:
            shutil.rmtree(scratch, ignore_errors=True)
    return merge_chunks(out, [lo for lo, _ in job.chunks()], job.meta)


__all__ = ["APPLICATIONS", "JOINT_CHUNK", "RESULTS", "JointApplication", "JointJob", "indices_of", "lookup_columns",
           "run_joint"]
