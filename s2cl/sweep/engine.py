"""The sweep engine: configurations in chunks → per-configuration metrics → Parquet, resumable,
on one process or on a Dask cluster.

Each chunk (a contiguous range of configuration numbers) is evaluated independently and
deterministically, and written as its own Parquet file the moment it finishes (temp file +
rename). A sweep killed at any moment and started again with the same command finds the
finished chunks, computes only the others, and ends with the same ``results.parquet``. The
folder's ``manifest.json`` holds the sweep's fingerprint (scene, tables, analysis, chunking,
s2cl version): a folder that holds another sweep is refused, not mixed.

On Dask (``--workers N`` for a local cluster, ``--scheduler ADDRESS`` for a running one) the
same chunks are tasks; the tables travel once to every worker, each worker builds its own
OpenCL context, and the client writes the chunk files, so the output equals the single-process
run bit for bit.
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import json
import shutil
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from s2cl.cl.runtime import get_runtime
from s2cl.errors import InputError
from s2cl.io.output import write_json
from s2cl.resources import code_fingerprint
from s2cl.retrieve.analysis import AnalysisSettings
from s2cl.retrieve.design import underdetermined
from s2cl.status import REGRESS_NAMES
from s2cl.sweep.addition import META_KEY as ADDITION_META
from s2cl.sweep.cluster import DASK_SCRATCH, dask_client
from s2cl.sweep.folder import CHUNKS, RESULTS, chunk_done, merge_chunks, write_chunk
from s2cl.sweep.kernel import SweepKernel
from s2cl.sweep.metrics_kernel import host_metrics
from s2cl.sweep.raw import ChunkEvaluator, variant_indices
from s2cl.sweep.tables import SweepTables
from s2cl.version import __version__

REGRESS_LABELS = {int(code): name for name, code in REGRESS_NAMES.items()}
MANIFEST = "manifest.json"
#: the folder of a multi-application sweep's applications' own sweeps (:mod:`s2cl.sweep.joint`)
APPLICATIONS = "applications"


@dataclass(frozen=True, eq=False)
class SweepJob:
    """Everything needed to evaluate any chunk of a sweep (picklable)."""

    tables: SweepTables
    analysis: AnalysisSettings
    chunk: int
    precision: str = "float32"
    #: pixels per work-item of the sweep kernel (None: the device's choice); not in the fingerprint,
    #: because lanes never change a result beyond the tested tolerance
    lanes: int | None = None
    #: the OpenCL device the scene asks for (None: default); the caller's ``device`` wins
    device: str | None = None
    scene_name: str = ""
    scene_text: str = ""
    #: ranking policy for designs the analysis cannot fit ("exclude" or "keep"; sweep.underdetermined)
    underdetermined: str = "exclude"
    #: a band-addition sweep (s2cl.sweep.addition): the base set's row of metrics, and the record of the
    #: addition (added band, base bands, metric, base score) from which each row's ``gain`` is taken
    base_row: dict[str, Any] | None = None
    addition: dict[str, Any] | None = None
    #: a search instead of the exhaustive sweep: its settings (s2cl.sweep.search.SearchSettings.record)
    search: dict[str, Any] | None = None

    @property
    def n_configs(self) -> int:
        return self.tables.n_configs

    def chunks(self) -> list[tuple[int, int]]:
        return [(lo, min(lo + self.chunk, self.n_configs)) for lo in range(0, self.n_configs, self.chunk)]

    def fingerprint(self) -> str:
        h = hashlib.sha256()
        h.update(self.tables.fingerprint().encode())
        # the chunk is not part of the identity: a configuration's metrics do not depend on its chunk
        # (s2cl.retrieve.metrics), and a resumed sweep keeps the chunk of its manifest (resumable_chunk)
        h.update(repr((self.analysis, self.precision, __version__, code_fingerprint())).encode())
        if self.addition is not None:
            h.update(json.dumps(self.addition, sort_keys=True).encode())
        if self.search is not None:
            h.update(json.dumps(self.search, sort_keys=True).encode())
        return h.hexdigest()

    def columns(self) -> list[str]:
        cols = ["config"]
        for b in self.tables.bands:
            cols += [f"{b}_centre_nm", f"{b}_width_nm"]
        return cols


# -- evaluating one chunk (in any process) -------------------------------------------------------

_EVALUATORS: dict[tuple[str, str | None], ChunkEvaluator] = {}


#: fingerprints of the sweeps whose kernels a process keeps together: a multi-application sweep's applications
#: (:func:`keep_together`); any other sweep's are kept alone
_TOGETHER: set[str] = set()


def keep_together(fingerprints: Iterable[str]) -> None:
    """Keep the kernels (and per-design statistics) of the sweeps with these job fingerprints side by side, instead of
    each new sweep's dropping the previous one's: a multi-application sweep checks every application's kernel, runs
    each application's sweep, then scores each one's reference, within-noise and margin designs, on one build per
    application. A sweep outside the group drops them all (memory holds one sweep's, or one group's, kernels)."""
    _TOGETHER.clear()
    _TOGETHER.update(fingerprints)


def last_one(cache: dict[Any, Any], key: Any, make: Callable[[], Any]) -> Any:
    """``cache[key]``, made by ``make()`` and kept alone (a process works on one sweep at a time: a new key drops the
    previous sweep's kernels), or beside the others of its group when the key's first part (a job's fingerprint) is
    in the group of :func:`keep_together` (the applications of one multi-application sweep)."""
    if key not in cache:
        value = make()
        grouped = _fingerprint_of(key) in _TOGETHER
        for old in [k for k in cache if not (grouped and _fingerprint_of(k) in _TOGETHER)]:
            del cache[old]
        cache[key] = value
    return cache[key]


def _fingerprint_of(key: Any) -> Any:
    """The job fingerprint a cache key starts with (the key itself when it is no tuple)."""
    return key[0] if isinstance(key, tuple) and key else key


def kernel_evaluator(job: SweepJob, device: str | None = None) -> ChunkEvaluator:
    """The fused sweep kernel for ``job`` on ``device`` (built once per process and job)."""
    device = device or job.device
    return last_one(_EVALUATORS, (job.fingerprint(), device),
                    lambda: SweepKernel(job.tables, job.analysis, get_runtime(device), precision=job.precision,
                                        lanes=job.lanes))


def evaluate_chunk(job: SweepJob, start: int, stop: int, device: str | None = None,
                   evaluator: ChunkEvaluator | None = None) -> dict[str, np.ndarray]:
    """Rows of configurations ``start … stop-1``: band centres/widths and metrics (columns → arrays).

    :param evaluator: computes the per-pixel results (default: :func:`kernel_evaluator` on ``device``;
        tests and bench pass the float64 numpy twin).
    """
    ev = evaluator or kernel_evaluator(job, device)
    t = job.tables
    rows: dict[str, np.ndarray] = {"config": np.arange(start, stop, dtype=np.int64)}
    idx = variant_indices(t, start, stop)
    centres = np.stack([t.centre[k][idx[:, k]] for k in range(t.n_slots)], axis=1)
    widths = np.stack([t.width[k][idx[:, k]] for k in range(t.n_slots)], axis=1)
    for k, b in enumerate(t.bands):
        rows[f"{b}_centre_nm"] = centres[:, k]
        rows[f"{b}_width_nm"] = widths[:, k]
    a = job.analysis
    rows["underdetermined"] = underdetermined(a, centres, widths)
    # the kernel computes its metrics on the device where it can; any other evaluator gives per-pixel results
    metrics = getattr(ev, "metrics", None)
    m = metrics(start, stop) if metrics else host_metrics(a, ev(start, stop), t.target, len(t.class_names))
    for k, v in m.items():
        rows[k] = np.asarray(v)
    if job.addition is not None:  # a band-addition sweep: the gain over the base set alone (positive: better)
        rows["gain"] = job.addition["base_score"] - rows[job.addition["metric"]]
    return rows


# -- the folder: manifest, chunk files, results ------------------------------------------------------

def _manifest(job: SweepJob) -> dict[str, Any]:
    return {"fingerprint": job.fingerprint(), "code": code_fingerprint(), "scene": job.scene_name,
            "s2cl_version": __version__,
            "configurations": job.n_configs, "chunk": job.chunk, "bands": list(job.tables.bands),
            "counts": list(job.tables.counts), "analysis": job.analysis.kind,
            "precision": job.precision, "created": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")}


#: files a finished sweep writes beside its chunks (``--overwrite`` removes them with the chunks)
DERIVED = (RESULTS, "summary.json", "heatmap_*.png")


def read_manifest(out: Path) -> dict[str, Any] | None:
    """The manifest of the sweep in folder ``out``; None when there is none.

    :raises InputError: a manifest that cannot be read (``--overwrite`` starts afresh).
    """
    manifest = out / MANIFEST
    if not manifest.exists():
        return None
    try:
        old = json.loads(manifest.read_text())
    except (OSError, json.JSONDecodeError, UnicodeDecodeError) as err:
        raise InputError(f"unreadable sweep manifest ({type(err).__name__}); use --overwrite to start afresh",
                         source=manifest) from None
    if not isinstance(old, dict):
        raise InputError("unreadable sweep manifest (not a JSON object); use --overwrite to start afresh",
                         source=manifest)
    return old


def resumable_chunk(out: str | Path, overwrite: bool = False) -> int | None:
    """The chunk size of the sweep already in folder ``out`` (its chunk files are keyed by it), so that
    the same command resumes it under any memory budget; None when there is none or ``overwrite``."""
    if overwrite:
        return None
    try:
        old = read_manifest(Path(out))
    except InputError:
        return None
    chunk = old.get("chunk") if old else None
    return chunk if isinstance(chunk, int) and not isinstance(chunk, bool) and chunk > 0 else None


def _remove_sweep_files(out: Path) -> None:
    """Chunks, results and everything derived from them (summary, heatmaps): another sweep replaces them."""
    shutil.rmtree(out / CHUNKS, ignore_errors=True)
    shutil.rmtree(out / APPLICATIONS, ignore_errors=True)  # a multi-application sweep's own sweeps
    for pattern in DERIVED:
        for p in out.glob(pattern):
            if p.is_file() or p.is_symlink():
                p.unlink(missing_ok=True)


def check_folder(job: SweepJob | Any, out: Path, *, overwrite: bool = False) -> dict[str, Any] | None:
    """Refuse a folder that holds another sweep (or this sweep in other chunks) unless ``overwrite``; the
    folder's manifest, if any. ``job``: a :class:`SweepJob`, or a job with its ``fingerprint()`` and ``chunk`` (a
    multi-application sweep's joint table, :class:`s2cl.sweep.joint.JointJob`). Reads only: the CLI calls it
    before the folder is claimed."""
    old = read_manifest(out)
    if old is not None and old.get("fingerprint") != job.fingerprint():
        if not overwrite and old.get("code") != code_fingerprint():
            raise InputError(
                f"the folder holds a sweep of scene {old.get('scene')!r} computed by other s2cl code (sources or "
                f"kernels changed since {old.get('created')}), whose chunks cannot be mixed with this code's; "
                "pass --overwrite to recompute it, or choose another --output", source=out)
        if not overwrite:
            raise InputError(
                f"the folder holds a different sweep (scene {old.get('scene')!r}, {old.get('configurations')} "
                f"configurations, created {old.get('created')}); rerun the same scene to resume it, or pass "
                "--overwrite to replace it, or choose another --output",
                source=out)
    if old is not None and old.get("fingerprint") == job.fingerprint() and old.get("chunk") != job.chunk \
            and not overwrite:
        raise InputError(f"the sweep in this folder runs in chunks of {old.get('chunk')}, not {job.chunk}; resume "
                         f"it without --chunk (or with --chunk {old.get('chunk')}), or pass --overwrite to start "
                         "afresh", source=out, key="--chunk")
    if old is None and not overwrite and _has_sweep_files(out):
        raise InputError("the folder holds sweep files without a manifest; pass --overwrite", source=out)
    return old


def prepare_folder(job: SweepJob | Any, out: Path, *, overwrite: bool = False,
                   manifest: dict[str, Any] | None = None) -> list[tuple[int, int]]:
    """Create or check the output folder; return the chunks still to compute.

    Crash-safe order: the manifest is written (atomically) before ``chunks/`` is made and old files are
    removed before a new manifest is written, so a run killed at any moment leaves a folder that the same
    command resumes: a manifest whose chunks are its own, or no manifest and an empty ``chunks/``. ``manifest``:
    the manifest of a job that is not a :class:`SweepJob` (a multi-application sweep's joint table,
    :class:`s2cl.sweep.joint.JointJob`: it has the same ``fingerprint()``, ``chunk`` and ``chunks()``).
    """
    old = check_folder(job, out, overwrite=overwrite)
    if overwrite or old is None or old.get("fingerprint") != job.fingerprint():
        if overwrite or old is not None:
            _remove_sweep_files(out)
        write_json(out / MANIFEST, manifest if manifest is not None else _manifest(job))
    (out / CHUNKS).mkdir(parents=True, exist_ok=True)
    return [(lo, hi) for lo, hi in job.chunks() if not chunk_done(out, lo, hi)]


def _has_sweep_files(out: Path) -> bool:
    """Results or chunk files: an empty ``chunks/`` (a run killed before its manifest) is no sweep."""
    chunks = out / CHUNKS
    return (out / RESULTS).exists() or (chunks.is_dir() and any(chunks.iterdir())) or \
        (chunks.exists() and not chunks.is_dir())


def merge_results(job: SweepJob, out: Path) -> Path:
    """All chunk files, in configuration order, as ``results.parquet`` with the sweep's metadata
    (:func:`s2cl.sweep.folder.merge_chunks`)."""
    return merge_chunks(out, [lo for lo, _ in job.chunks()], results_meta(job))


def results_meta(job: SweepJob) -> dict[bytes, bytes]:
    """The schema metadata of a sweep's ``results.parquet`` (scene, fingerprint, analysis, bands, policies)."""
    meta = {b"s2cl_version": __version__.encode(), b"scene": job.scene_name.encode(),
            b"scene_toml": job.scene_text.encode(), b"fingerprint": job.fingerprint().encode(),
            b"analysis": job.analysis.kind.encode(), b"bands": json.dumps(list(job.tables.bands)).encode(),
            b"underdetermined": job.underdetermined.encode(),
            b"regress": json.dumps([REGRESS_LABELS[c] for c in job.analysis.regress]).encode()}
    if job.addition is not None:
        meta[ADDITION_META.encode()] = json.dumps(job.addition).encode()
    if job.search is not None:
        meta[b"search"] = json.dumps(job.search).encode()
    return meta


# -- estimates --------------------------------------------------------------------------------------

def results_disk_bytes(n_configs: int, n_slots: int) -> float:
    """Disk the chunk files and ``results.parquet`` of a sweep take at most (bytes): both hold every row
    (config, centre and width per band, about ten metrics), float64, with Parquet overhead."""
    return n_configs * (2 * n_slots + 11) * 8 * 1.3 + 1e6


# -- running ------------------------------------------------------------------------------------------

Progress = Callable[[int], None]


def run_sweep(job: SweepJob, out: str | Path, *, workers: int | None = None, scheduler: str | None = None,
              overwrite: bool = False, device: str | None = None, progress: Progress | None = None,
              on_start: Callable[[int, int], None] | None = None, evaluator: ChunkEvaluator | None = None
              ) -> Path:
    """Run (or resume) a sweep into folder ``out``; returns the path of ``results.parquet``.

    :param device: the OpenCL device of every chunk, here and on Dask workers (each builds its own context).
    :param on_start: called with (configurations to compute, configurations already done).
    :param evaluator: a picklable chunk evaluator instead of the kernel (tests and bench: the numpy twin).

    The chunk's memory and the results' disk are planned before the job is made
    (:func:`s2cl.app.sweep_budget.sweep_resources`, :func:`s2cl.app.sweep_budget.require_sweep_disk`).
    """
    out = Path(out)
    todo = prepare_folder(job, out, overwrite=overwrite)
    done = job.n_configs - sum(hi - lo for lo, hi in todo)
    if on_start:
        on_start(job.n_configs - done, done)
    if todo:
        if workers or scheduler:
            results = _run_dask(job, todo, workers, scheduler, device, evaluator, out / DASK_SCRATCH)
        else:
            results = ((lo, evaluate_chunk(job, lo, hi, device, evaluator)) for lo, hi in todo)
        for lo, rows in results:
            write_chunk(out, lo, rows)
            if progress:
                progress(len(rows["config"]))
        if not (workers or scheduler or evaluator):  # the chunks' buffers go back before the merge and the report
            get_runtime(device or job.device).free_held()
    return merge_results(job, out)


def _run_dask(job: SweepJob, todo: list[tuple[int, int]], workers: int | None, scheduler: str | None,
              device: str | None, evaluator: ChunkEvaluator | None,
              scratch: Path) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
    with dask_client(workers, scheduler, scratch) as client:
        from dask.distributed import as_completed

        shared = client.scatter(job, broadcast=True)
        futures = {client.submit(evaluate_chunk, shared, lo, hi, device, evaluator, pure=False): lo
                   for lo, hi in todo}
        for future in as_completed(futures):
            yield futures[future], future.result()
