"""A sweep's files: one Parquet file per finished chunk (``chunks/part-START.parquet``, written atomically
the moment the chunk finishes) and ``results.parquet``, all chunks in configuration order with the
sweep's metadata (written in row groups of :data:`ROW_GROUP_ROWS` rows, whatever the chunk size)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from s2cl.io.output import atomic_path

RESULTS = "results.parquet"
CHUNKS = "chunks"


def chunk_path(out: Path, start: int) -> Path:
    return out / CHUNKS / f"part-{start:010d}.parquet"


def chunk_done(out: Path, start: int, stop: int) -> bool:
    path = chunk_path(out, start)
    if not path.exists():
        return False
    import pyarrow.parquet as pq

    try:
        meta = pq.read_metadata(path)
    except Exception:  # a damaged file is recomputed
        return False
    return meta.num_rows == stop - start


def write_chunk(out: Path, start: int, rows: dict[str, np.ndarray]) -> Path:
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table(rows)
    path = chunk_path(out, start)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
    return path


#: rows per row group of ``results.parquet``: the file's layout does not depend on the chunk size, and a
#: reader (:mod:`s2cl.sweep.digest`) holds one group at a time
ROW_GROUP_ROWS = 65_536


def merge_chunks(out: Path, starts: list[int], meta: dict[bytes, bytes]) -> Path:
    """The chunk files starting at ``starts`` (in order) as ``results.parquet`` with schema metadata ``meta``,
    written :data:`ROW_GROUP_ROWS` rows at a time (memory: one chunk and one row group, whatever the sweep's
    size)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = out / RESULTS
    with atomic_path(path) as tmp:
        writer, pending, rows = None, [], 0
        try:
            for lo in starts:
                table = pq.read_table(chunk_path(out, lo))
                if writer is None:
                    schema = table.schema.with_metadata({**(table.schema.metadata or {}), **meta})
                    writer = pq.ParquetWriter(tmp, schema)
                pending.append(table.replace_schema_metadata(writer.schema.metadata))
                rows += table.num_rows
                while rows >= ROW_GROUP_ROWS:
                    merged = pa.concat_tables(pending)
                    writer.write_table(merged.slice(0, ROW_GROUP_ROWS), row_group_size=ROW_GROUP_ROWS)
                    rest = merged.slice(ROW_GROUP_ROWS)
                    pending, rows = [rest], rest.num_rows
            if writer is not None and rows:
                writer.write_table(pa.concat_tables(pending), row_group_size=ROW_GROUP_ROWS)
        finally:
            if writer is not None:
                writer.close()
    return path
