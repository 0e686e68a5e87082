"""Where a sweep's trials run: in this process, on a local Dask cluster that the sweep starts and stops, or on an
existing Dask cluster (`dask scheduler` and `dask worker` on other machines, SSHCluster, dask-jobqueue).

Dask reschedules the tasks of a worker that dies; a trial is a pure function of its description, so a re-run
gives the same rows and the sweep still ends with every trial exactly once.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

CONNECT_TIMEOUT = 10.0
"""Seconds to reach a scheduler before saying it is unreachable."""


class ClusterError(RuntimeError):
    """The trials have nowhere to run (an unreachable scheduler); the message says which and why."""


def default_workers() -> int:
    """One worker process per core."""
    return os.cpu_count() or 1


@contextmanager
def open_client(workers: int | None, scheduler: str | None) -> Iterator[object | None]:
    """A dask.distributed Client for the trials, or None for `workers == 0` (every trial in this process).
    No scheduler: a local cluster of `workers` processes (default one per core), closed on leaving."""
    if scheduler is None and workers == 0:
        yield None
        return
    from dask.distributed import Client, LocalCluster
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as error:
            raise ClusterError(f'cannot reach the Dask scheduler {scheduler} within {CONNECT_TIMEOUT:g} s: '
                               f'{error}') from None
        try:
            yield client
        finally:
            client.close()
        return
    cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                           dashboard_address=None, silence_logs=50)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()
