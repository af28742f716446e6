"""Dask for sweeps and searches: reaching a scheduler before anything is created, and a client of it or of a
local cluster."""

from __future__ import annotations

import os
import shutil
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from s2cl.errors import DependencyError, InputError, token


def reach_scheduler(address: str, timeout: float = 10.0) -> None:
    """Reach the Dask scheduler at ``address`` (a TCP connection within ``timeout`` seconds, then closed): a
    one-line :class:`InputError` (key ``--scheduler``) before anything is created when the address is
    malformed or nothing listens there."""
    try:
        from distributed.comm.addressing import parse_address, parse_host_port
    except ImportError as err:
        raise DependencyError('Dask sweeps need dask.distributed: pip install "s2cl[dask]"') from err
    try:
        scheme, location = parse_address(address)
        host, port = parse_host_port(location)
    except (ValueError, TypeError) as err:
        raise InputError(f"{token(address, 80)} is not a scheduler address ({err}); give it as tcp://HOST:PORT",
                         key="--scheduler") from None
    if scheme not in ("tcp", "tls"):
        return  # other transports (inproc, ucx) are left to Dask
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except (OSError, ValueError, OverflowError) as err:
        reason = "timed out" if isinstance(err, TimeoutError) else (os.strerror(err.errno) if getattr(
            err, "errno", None) else type(err).__name__)
        raise InputError(f"cannot connect to the Dask scheduler {token(address, 80)} ({reason}; waited at most "
                         f"{timeout:g} s)", key="--scheduler") from None


#: Dask's scratch space of a local cluster, inside the output folder (removed when the run ends)
DASK_SCRATCH = ".dask-scratch"


@contextmanager
def dask_client(workers: int | None, scheduler: str | None, scratch: Path) -> Iterator[Any]:
    """A Dask client: of the running scheduler at ``scheduler``, else of a local cluster of ``workers`` processes
    (one thread each; scratch space in ``scratch``, removed at the end)."""
    try:
        import dask
        from dask.distributed import Client, LocalCluster
    except ImportError as err:
        raise DependencyError('Dask sweeps need dask.distributed: pip install "s2cl[dask]"') from err
    cluster = None
    try:
        if scheduler:
            try:
                client = Client(scheduler)
            except Exception as err:  # reachable, but not a scheduler that answers
                raise InputError(f"cannot use the Dask scheduler {token(scheduler, 80)} ({type(err).__name__})",
                                 key="--scheduler") from None
        else:
            with dask.config.set({"temporary-directory": str(scratch)}):
                cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None, local_directory=str(scratch))
            client = Client(cluster)
        try:
            yield client
        finally:
            client.close()
    finally:
        if cluster is not None:
            cluster.close()
        shutil.rmtree(scratch, ignore_errors=True)
