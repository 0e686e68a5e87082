"""A function run in a child process of its own, under a wall-time and a memory limit, its output thrown away, and
every process it started ended with it.

What a Webots-style script does is beyond our control: it may crash the interpreter, call `os._exit`, loop for
ever, print without end, allocate gigabytes, start processes, or fork and call setsid to leave its process group.
In a forked child none of that reaches the caller (a Dask worker, or `sweep` itself). Between the two sits a
keeper, a forked process that does nothing else: a child subreaper (`process_tree`), so every process the child
starts stays below it whatever it does; it watches the child's time and resident memory, and once the child has
ended (or is killed at a limit, or the caller goes) it kills everything left below it. The child's stdout and
stderr (file descriptors and Python's streams) go to /dev/null, so no pipe fills and no memory grows with its
output; its value comes back as JSON (never unpickled: a script must not reach the caller through it).

Forking (not a new interpreter) keeps the cost per trial to milliseconds: the child starts with every module the
parent has imported. The parent's other threads (a Dask worker's) do not exist in the keeper or the child; only a
lock one of them held at the fork could matter, and their code (the core, the script, json, /proc) takes none of
theirs. Whatever else happens, the keeper ends the child at its limits, and the caller's pipe closing (the caller
interrupted or dead) ends the keeper's watch.
"""
from __future__ import annotations

import gc
import json
import os
import select
import signal
import sys
import time
from collections.abc import Callable
from typing import Any, TypeVar

from epuck_ros.experiments.process_tree import become_subreaper, descendants, end_descendants, resident

T = TypeVar('T')
MAX_RESULT_BYTES = 64 << 20
MEMORY_PERIOD = 0.1
"""Wall seconds between two looks at the child's resident memory."""
TREE_PERIOD = 1.0
"""Wall seconds between two looks at the memory of the processes the child started (a walk through /proc)."""
KEEPER_GRACE = 30.0
"""Wall seconds the caller gives the keeper beyond the time limit before it kills the keeper itself."""


class ChildFailed(RuntimeError):
    """The child gave no value: it raised (the message is its error's), died, or went over a limit."""


def call_in_child(function: Callable[[Any], T], argument: Any, limit: float, memory: float) -> T:
    """`function(argument)` in a forked child; ChildFailed if it raises, dies, is not done within `limit` wall
    seconds or its processes take more than `memory` bytes of resident memory beyond what this process holds now
    (then it is killed, with every process it started). Its value must be JSON (lists, dicts, str, numbers)."""
    result_read, result_write = os.pipe()
    report_read, report_write = os.pipe()
    stop_read, stop_write = os.pipe()
    baseline = resident(os.getpid())
    gc.freeze()   # the child's collections then leave the parent's objects alone (no copy of every page they touch)
    keeper = os.fork()
    if keeper == 0:   # never returns
        for fd in (result_read, report_read, stop_write):
            os.close(fd)
        _keep(function, argument, (result_write, report_write, stop_read), limit, (baseline, memory))
    gc.unfreeze()
    for fd in (result_write, report_write, stop_read):
        os.close(fd)
    try:
        deadline = time.monotonic() + limit + KEEPER_GRACE
        data = _read_until(result_read, deadline, MAX_RESULT_BYTES)
        if data is None:   # too much, or too late: the keeper ends the child's processes now
            os.close(stop_write)
            stop_write = -1
        report = _read_until(report_read, deadline, 1 << 10)   # the keeper's, once the child has ended
    except BaseException:   # Ctrl-C or SIGTERM in the caller: the keeper ends the child's processes
        if stop_write >= 0:
            os.close(stop_write)
            stop_write = -1
        os.waitpid(keeper, 0)
        raise
    finally:
        for fd in (result_read, report_read, stop_write):
            if fd >= 0:
                os.close(fd)
    if report is None:   # the keeper did not end its watch: it goes
        os.kill(keeper, signal.SIGKILL)
    _ending.append(keeper)
    _reap()
    return _outcome(data, report, limit, memory)


_ending: list[int] = []
"""Keepers that have reported and are ending: reaped when they have (their exit, the unmapping of a copy of this
process, is no part of the trial's time)."""


def _reap() -> None:
    for keeper in list(_ending):
        try:
            if not os.waitpid(keeper, os.WNOHANG)[0]:
                continue
        except ChildProcessError:   # reaped by someone else's wait for any child
            pass
        _ending.remove(keeper)


def _outcome(data: bytes | None, report: bytes | None, limit: float, memory: float) -> Any:
    """The child's value, or ChildFailed saying what happened."""
    if report is None:
        raise ChildFailed('the trial\'s keeper did not end its processes in time: killed')
    why, detail = json.loads(report)
    if why == 'limit':
        raise ChildFailed(f'no result within {limit:g} wall seconds (the time limit): the trial\'s process was '
                          'killed')
    if why == 'memory':
        raise ChildFailed(f'{detail / 1e6:.0f} MB of resident memory, more than {memory / 1e6:.0f} (the memory '
                          'limit): the trial\'s processes were killed')
    if data is None:
        raise ChildFailed(f'a result of more than {MAX_RESULT_BYTES} bytes')
    if not data:
        raise ChildFailed(_how_it_ended(detail) if why == 'ended' else 'the trial\'s process ended before its result')
    try:
        kind, value = json.loads(data)
    except (ValueError, TypeError):
        raise ChildFailed('the trial\'s result was garbled (a process it started wrote to its channel)') from None
    if kind == 'error':
        raise ChildFailed(str(value))
    return value


def _keep(function: Callable[[Any], Any], argument: Any, pipes: tuple[int, int, int], limit: float,
          memory: tuple[int, float]) -> None:
    """The keeper: start the child, watch it, end its processes, report why it ended ([why, detail] as JSON).
    `pipes`: the child's result (write end), the report (write end), the caller's stop (read end); `memory`: the
    caller's resident bytes and the bytes the child may take beyond them."""
    result_write, report_write, stop_read = pipes
    try:
        for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):   # it ends when the caller's pipe closes
            signal.signal(number, signal.SIG_IGN)
        become_subreaper()
        child = os.fork()
        if child == 0:
            os.close(report_write)
            os.close(stop_read)
            _child(function, argument, result_write)
        os.close(result_write)
        try:
            os.setpgid(child, child)   # as the child does: whichever runs first, the group exists before any kill
        except OSError:   # the child has already ended
            pass
        why, detail = _watch(child, stop_read, time.monotonic() + limit, *memory)
        for kill in (os.killpg, os.kill):   # at once, most of what it started (its process group), and itself:
            try:                            # not reaped yet, so neither number can be another process's now
                kill(child, signal.SIGKILL)
            except OSError:
                pass
        _, status = os.waitpid(child, 0)
        if why == 'ended':
            detail = status
        end_descendants()   # then what left the group (setsid) or was orphaned
        os.write(report_write, json.dumps([why, detail]).encode())
    finally:
        os._exit(0)


def _watch(child: int, stop_read: int, deadline: float, baseline: int, memory: float) -> tuple[str, Any]:
    """Until the child ends ('ended'), goes over the time limit ('limit') or its processes' resident
    memory over `baseline` + `memory` bytes ('memory', the bytes over `baseline`), or the caller closes its pipe
    ('stopped')."""
    try:
        ended = os.pidfd_open(child)   # readable once the child has ended
        watched, period = [stop_read, ended], MEMORY_PERIOD
    except (AttributeError, OSError):   # no pidfd: look often
        watched, period = [stop_read], 0.005
    others, next_walk = 0, time.monotonic() + TREE_PERIOD
    while True:
        if os.waitid(os.P_PID, child, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None:   # ended, not reaped
            return 'ended', None
        now = time.monotonic()
        if now >= deadline:
            return 'limit', None
        if now >= next_walk:   # the processes the child started (rarely any)
            others = sum(size for pid, size in descendants(os.getpid()).items() if pid != child)
            next_walk = now + TREE_PERIOD
        grown = resident(child) + others - baseline
        if grown > memory:
            return 'memory', grown
        if stop_read in select.select(watched, [], [], min(period, deadline - now))[0]:
            return 'stopped', None


def _child(function: Callable[[Any], Any], argument: Any, write_end: int) -> None:
    try:
        os.setpgid(0, 0)   # its own process group: a kill takes whatever it started along at once
        quiet = os.open(os.devnull, os.O_WRONLY)
        os.dup2(quiet, 1)
        os.dup2(quiet, 2)
        sys.stdout = sys.stderr = open(quiet, 'w', closefd=False)
        signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the caller's to handle: it ends the child
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGHUP, signal.SIG_DFL)
        try:
            result = ['value', function(argument)]
        except BaseException as error:  # noqa: BLE001 - whatever it was, the parent gets one line
            message = str(error) if isinstance(error, ChildFailed) else f'{type(error).__name__}: {error}'
            result = ['error', message]
        try:
            data = json.dumps(result).encode()
        except (TypeError, ValueError) as error:
            data = json.dumps(['error', f'a result JSON cannot carry: {error}']).encode()
        if len(data) > MAX_RESULT_BYTES:
            data = json.dumps(['error', f'a result of {len(data)} bytes, more than {MAX_RESULT_BYTES}']).encode()
        with os.fdopen(write_end, 'wb') as out:
            out.write(data)
    finally:
        os._exit(0)


def _read_until(fd: int, deadline: float, most: int) -> bytes | None:
    """Everything written to `fd` until its writers close it; None if that did not happen before `deadline`
    (monotonic) or it was more than `most` bytes."""
    chunks, size = [], 0
    while True:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            return None
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            return b''.join(chunks)
        chunks.append(chunk)
        size += len(chunk)
        if size > most:
            return None


def _how_it_ended(status: int) -> str:
    if os.WIFSIGNALED(status):
        return f'the trial\'s process was killed by {signal.Signals(os.WTERMSIG(status)).name} before its result'
    return f'the trial\'s process ended (exit code {os.waitstatus_to_exitcode(status)}) before its result'
