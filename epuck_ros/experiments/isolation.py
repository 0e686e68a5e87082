"""A function run in a child process of its own, under a wall-time limit, its output thrown away.

What a Webots-style script does is beyond our control: it may crash the interpreter, call `os._exit`, loop for
ever, or print without end. In a forked child none of that reaches the caller (a Dask worker, or `sweep` itself):
the child is killed at the limit with everything it started (its own process group), its stdout and stderr
(file descriptors and Python's streams) go to /dev/null, so no pipe fills and no memory grows with its output,
and the caller gets the function's value or one line saying what happened.

Forking (not a new interpreter) keeps the cost per trial to milliseconds: the child starts with every module the
parent has imported. The parent's other threads (a Dask worker's) do not exist in the child; only a lock one of
them held at the fork could matter, and the child's code (the core, the script, pickle) takes none of theirs.
Whatever else happens, the time limit ends it.
"""
from __future__ import annotations

import gc
import os
import pickle
import select
import signal
import sys
import time
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar('T')
MAX_RESULT_BYTES = 64 << 20


class ChildFailed(RuntimeError):
    """The child gave no value: it raised (the message is its error's), died, or ran out of time."""


def call_in_child(function: Callable[[Any], T], argument: Any, limit: float) -> T:
    """`function(argument)` in a forked child; ChildFailed if it raises, dies or is not done within `limit` wall
    seconds (then it is killed, with every process it started)."""
    read_end, write_end = os.pipe()
    gc.freeze()   # the child's collections then leave the parent's objects alone (no copy of every page they touch)
    pid = os.fork()
    if pid == 0:   # the child: never returns
        os.close(read_end)
        _child(function, argument, write_end)
    gc.unfreeze()
    os.close(write_end)
    try:
        os.setpgid(pid, pid)   # as the child does: whichever runs first, the group exists before any kill
    except (PermissionError, ProcessLookupError):   # the child has already exec'd or ended
        pass
    try:
        data = _read_until(read_end, time.monotonic() + limit)
    except BaseException:   # Ctrl-C in the caller: the child goes with it
        _kill(pid)
        raise
    finally:
        os.close(read_end)
    if data is None:
        _kill(pid)
        raise ChildFailed(f'no result within {limit:g} wall seconds (the time limit): the trial\'s process was '
                          f'killed')
    _, status = os.waitpid(pid, 0)
    if not data:
        raise ChildFailed(_how_it_ended(status))
    kind, value = pickle.loads(data)
    if kind == 'error':
        raise ChildFailed(value)
    return value


def _child(function: Callable[[Any], Any], argument: Any, write_end: int) -> None:
    try:
        os.setpgid(0, 0)   # its own process group: a kill at the limit takes whatever it started along
        quiet = os.open(os.devnull, os.O_WRONLY)
        os.dup2(quiet, 1)
        os.dup2(quiet, 2)
        sys.stdout = sys.stderr = open(quiet, 'w', closefd=False)
        signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C is the caller's to handle: it kills the child
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        try:
            result = ('value', function(argument))
        except BaseException as error:  # noqa: BLE001 - whatever it was, the parent gets one line
            message = str(error) if isinstance(error, ChildFailed) else f'{type(error).__name__}: {error}'
            result = ('error', message)
        data = pickle.dumps(result)
        if len(data) > MAX_RESULT_BYTES:
            data = pickle.dumps(('error', f'a result of {len(data)} bytes, more than {MAX_RESULT_BYTES}'))
        with os.fdopen(write_end, 'wb') as out:
            out.write(data)
    finally:
        os._exit(0)


def _read_until(fd: int, deadline: float) -> bytes | None:
    """Everything written to `fd` until its writer closes it; None if that did not happen before `deadline`."""
    chunks = []
    while True:
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            return None
        chunk = os.read(fd, 1 << 16)
        if not chunk:
            return b''.join(chunks)
        chunks.append(chunk)


def _kill(pid: int) -> None:
    try:
        os.killpg(pid, signal.SIGKILL)
    except ProcessLookupError:
        os.kill(pid, signal.SIGKILL)
    os.waitpid(pid, 0)


def _how_it_ended(status: int) -> str:
    if os.WIFSIGNALED(status):
        return f'the trial\'s process was killed by {signal.Signals(os.WTERMSIG(status)).name} before its result'
    return f'the trial\'s process ended (exit code {os.waitstatus_to_exitcode(status)}) before its result'
