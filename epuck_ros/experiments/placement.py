"""Where a local Dask cluster's workers run: each worker process on one core of its own (`OneCorePerWorker`).

Kept apart from `cluster` so that a sweep in this process (`--workers 0`) does not import dask.distributed.
"""
from __future__ import annotations

import os
from typing import Any

from distributed import WorkerPlugin


class OneCorePerWorker(WorkerPlugin):
    """A Dask worker plugin: every thread of the worker process on one core, worker i on the i-th core this process
    may use (round robin), set again when the nanny restarts a worker (a plugin's `setup` runs on new workers too).

    Why: a worker runs its task (a trial) in a thread while its event loop (heartbeats, the scheduler's messages,
    the profiler every 10 ms) lives in the main thread. A trial releases the GIL for a moment many times per step
    (each of NumPy's `Generator` draws of the sensor noise), and in CPython each release wakes a thread waiting for
    the GIL; on another core the woken event loop nearly always finds it taken again, so it waits on, woken once
    per release (its own 5 ms switch interval starts anew each time), and every such wake-up is a futex call and a
    cross-core wake-up paid by the trial's thread. A trial then took more CPU in a worker than in the sweep's own
    process (`benchmarks/bench_sweep.py --sweep-only`: Dask's overhead per trial). On one core the woken thread
    takes the GIL at the first release and the trial runs as fast as alone. Neither malloc trimming (no page faults
    per trial), the garbage collector, the profiler alone nor BLAS threads (Dask sets them to 1) made the difference.
    A cluster of your own (`--scheduler`) is yours to place: `taskset -c K dask worker ... --nthreads 1` per core
    does the same."""

    idempotent = True

    def setup(self, worker: Any) -> None:
        if not hasattr(os, 'sched_setaffinity') or not isinstance(worker.name, int):
            return   # not Linux, or not a worker of the LocalCluster (named 0, 1, ...)
        cores = sorted(os.sched_getaffinity(0))
        core = {cores[worker.name % len(cores)]}
        for thread in os.listdir('/proc/self/task'):   # each thread; threads started later inherit it
            try:
                os.sched_setaffinity(int(thread), core)
            except OSError:   # a thread that has just ended
                pass
