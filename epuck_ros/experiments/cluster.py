"""Where a sweep's trials run: in this process, on a local Dask cluster that the sweep starts and stops, or on an
existing Dask cluster (`dask scheduler` and `dask worker` on other machines, SSHCluster, dask-jobqueue).

Dask reschedules the tasks of a worker that dies; a trial is a pure function of its description, so a re-run
gives the same rows and the sweep still ends with every trial exactly once.
"""
from __future__ import annotations

import argparse
import asyncio
import os
import signal
import socket
import threading
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar
from urllib.parse import urlsplit

from epuck_ros import untrusted_yaml

T = TypeVar('T')
PIN_LOCAL_WORKERS = True
"""Whether a local cluster keeps each worker process on a core of its own (`placement.OneCorePerWorker`)."""

CONNECT_TIMEOUT = 5.0
"""Seconds for a TCP connection to a scheduler's address before saying it is unreachable (refused: at once)."""
WORKERS_PER_CORE = 4
"""`--workers` at most this many per core of this machine."""
MAX_FIRST_FRAME = 1 << 20
"""Bytes; a Dask scheduler's first frame (its handshake) is far smaller. A larger length is no Dask peer's: an SSH
server's banner read as a length asks for exabytes."""
SCHEDULER_TIMEOUT = 8.0
"""Seconds for the whole connection to a scheduler, TCP, Dask's handshake and the client's registration: a port
that accepts but never answers as a scheduler is one line and exit 2 within 10 s of the sweep's start, not a wait
(Dask's own handshake read has no time-out)."""


class ClusterError(RuntimeError):
    """The trials have nowhere to run (an unreachable scheduler); the message says which and why."""


def default_workers() -> int:
    """One worker process per core."""
    return os.cpu_count() or 1


def max_workers() -> int:
    """Local workers at most: a trial keeps a core busy, so beyond a few per core workers only cost memory (each
    is a Python process with NumPy and Dask loaded) and start-up time."""
    return WORKERS_PER_CORE * default_workers()


def add_cluster_arguments(parser: argparse.ArgumentParser, work: str) -> None:
    """`--workers` and `--scheduler`, as `sweep` and `evolve` take them; `work` names what runs ('every trial')."""
    parser.add_argument('--workers', type=int, default=None,
                        help=f'local Dask worker processes (default: one per core, here {default_workers()}); '
                             f'0 = {work} in this process, one after the other')
    parser.add_argument('--scheduler', help='tcp://HOST:PORT of an existing Dask scheduler (its workers need '
                                            'epuck_ros installed)')


def check_cluster_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse (exit 2, one line) what `add_cluster_arguments` cannot take."""
    if args.workers is not None and args.workers < 0:
        parser.error('--workers must be 0 or more')
    if args.workers is not None and args.workers > max_workers():
        parser.error(f'--workers must be at most {max_workers()} ({WORKERS_PER_CORE} per core)')
    if args.workers is not None and args.scheduler is not None:
        parser.error('--workers and --scheduler: the workers of the cluster at --scheduler run the work; give one')


@contextmanager
def open_client(workers: int | None, scheduler: str | None,
                allowed_failures: int | None = None) -> Iterator[object | None]:
    """A dask.distributed Client for the trials, or None for `workers == 0` (every trial in this process).
    No scheduler: a local cluster of `workers` processes (default one per core), closed on leaving, whose scheduler
    gives up on a task after `allowed_failures` deaths of the workers running it (default: Dask's, 3)."""
    if scheduler is None and workers == 0:
        yield None
        return
    from dask.distributed import Client, LocalCluster
    if scheduler is not None:
        deadline = time.monotonic() + SCHEDULER_TIMEOUT
        address = _probe(scheduler, deadline)
        try:
            client = Client(address, timeout=max(0.1, deadline - time.monotonic()))
        except Exception as error:  # noqa: BLE001 - whatever the peer made of Dask's handshake: one line
            raise ClusterError(f'cannot reach the Dask scheduler {scheduler} within {SCHEDULER_TIMEOUT:g} s: '
                               f'{_said(error)}') from None
        try:
            yield client
        finally:
            client.close()
        return
    # The worker processes start with Ctrl-C ignored (inherited): Ctrl-C in the terminal reaches the whole process
    # group, and it is the caller's to handle (it closes the cluster); each worker printed a KeyboardInterrupt.
    try:
        with _without_ctrl_c():
            cluster = LocalCluster(n_workers=workers or default_workers(), threads_per_worker=1, processes=True,
                                   dashboard_address=':0', silence_logs=50,
                                   scheduler_kwargs={'allowed_failures': allowed_failures})
    except BaseException:
        _stop_resource_tracker()   # a cluster whose workers failed to start leaves it running as well
        raise
    client = Client(cluster)
    try:
        if PIN_LOCAL_WORKERS:   # else a trial takes more CPU in a worker (placement.py says why)
            from epuck_ros.experiments.placement import OneCorePerWorker
            client.register_plugin(OneCorePerWorker(), name='epuck_ros-one-core-per-worker')
        yield client
    finally:
        with _without_ctrl_c():   # a close cut short by Ctrl-C left the worker processes running
            client.close()
            cluster.close()
        _stop_resource_tracker()


def _stop_resource_tracker() -> None:
    """End multiprocessing's resource tracker, started for the local cluster's workers: it waits for our end of its
    pipe to close, so it outlived a sweep by a moment and stayed for as long as any other caller lived (a stray
    process for whoever looks). Python offers no public call for it; without the private one it ends with this
    process. A later cluster starts a new one."""
    from multiprocessing import resource_tracker
    stop = getattr(resource_tracker._resource_tracker, '_stop', None)
    if stop is not None:
        stop()


@contextmanager
def _without_ctrl_c() -> Iterator[None]:
    """SIGINT ignored meanwhile (only the main thread may change it; elsewhere nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    handler = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, handler)


def _probe(scheduler: str, deadline: float) -> str:
    """The tcp:// address of a Dask scheduler at `scheduler` (tcp://HOST:PORT or HOST:PORT), or ClusterError: at once
    when nothing listens (Dask's connect retries until its timeout), when what listens first says something that is
    no Dask frame (an SSH server's banner), or when it does not answer Dask's handshake before `deadline`
    (monotonic; Dask's own handshake read waits for ever)."""
    scheme = scheduler.partition('://')[0] if '://' in scheduler else 'tcp'
    if scheme != 'tcp':
        why = {'tls': 'tls:// needs certificates, which sweep and evolve do not take',
               'ucx': 'ucx:// needs UCX, which this package does not install'}.get(scheme, f'not {scheme}://')
        raise ClusterError(f'--scheduler {scheduler}: only tcp://HOST:PORT addresses are taken ({why})')
    parts = urlsplit(scheduler if '://' in scheduler else f'tcp://{scheduler}')
    try:
        port = parts.port
    except ValueError:
        port = None
    if not parts.hostname or port is None or parts.path not in ('', '/') or parts.query or parts.fragment:
        raise ClusterError(f'--scheduler {scheduler}: expected tcp://HOST:PORT')
    try:
        with socket.create_connection((parts.hostname, port), timeout=CONNECT_TIMEOUT) as connection:
            connection.settimeout(max(0.1, deadline - time.monotonic()))
            first = b''
            while len(first) < 8:   # a Dask peer speaks first: the length of its handshake frame
                chunk = connection.recv(8 - len(first))
                if not chunk:
                    break
                first += chunk
    except TimeoutError:
        raise ClusterError(f'cannot reach the Dask scheduler {scheduler} within {SCHEDULER_TIMEOUT:g} s: no answer as '
                           'a Dask scheduler') from None
    except OSError as error:
        raise ClusterError(f'cannot reach the Dask scheduler {scheduler}: {error.strerror or error}') from None
    if len(first) < 8 or int.from_bytes(first, 'little') > MAX_FIRST_FRAME:
        shown = untrusted_yaml.cut(repr(first.decode('ascii', 'replace')), 40) if first else 'nothing'
        raise ClusterError(f'{scheduler} is not a Dask scheduler: it said {shown} where a Dask peer starts its '
                           'handshake')
    address = f'tcp://{parts.netloc}'
    try:
        asyncio.run(_handshake(address, max(0.1, deadline - time.monotonic())))
    except Exception as error:  # noqa: BLE001 - whatever the peer made of the handshake: one line
        raise ClusterError(f'cannot reach the Dask scheduler {scheduler} within {SCHEDULER_TIMEOUT:g} s: '
                           f'{_said(error)}') from None
    return address


def _said(error: Exception) -> str:
    """An error of Dask's connection in a few words."""
    text = untrusted_yaml.cut(str(error), 200)
    return text if isinstance(error, (OSError, TimeoutError)) and text else \
        f'no answer as a Dask scheduler ({type(error).__name__}{": " + text if text else ""})'


async def _handshake(address: str, seconds: float) -> None:
    """Dask's comm handshake with `address`, all of it within `seconds` (asyncio.TimeoutError, else)."""
    from distributed.comm import connect
    comm = await asyncio.wait_for(connect(address, timeout=seconds), seconds)
    await comm.close()


def map_in_order(client: object | None, function: Callable[[Any], T], items: Iterable[Any],
                 retries: int = 2) -> list[T]:
    """`function(item)` for every item, results in the items' order: each item a task on the Dask `client` (from
    `open_client`), or one after the other in this process for None. `function` must be a pure, importable
    function (a worker runs it): Dask re-runs the tasks of a worker that dies, and `retries` times a task that
    raised, so a result never depends on which worker or attempt gave it."""
    items = list(items)
    if client is None:
        return [function(item) for item in items]
    return client.gather(client.map(function, items, pure=True, retries=retries))
