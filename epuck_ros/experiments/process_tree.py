"""A process's descendants, their resident memory and their end, from /proc (Linux).

Used by a script trial's keeper (`isolation`), which is a child subreaper (prctl PR_SET_CHILD_SUBREAPER): whatever
its trial starts stays its descendant, however it forks or calls setsid, because a process whose parent ends is
given to the nearest subreaper among its ancestors, not to init. So the keeper finds every process of the trial
below itself, and ends them all.
"""
from __future__ import annotations

import ctypes
import os
import signal

PAGE = os.sysconf('SC_PAGE_SIZE')
PR_SET_CHILD_SUBREAPER = 36
"""linux/prctl.h."""


try:
    _PRCTL = ctypes.CDLL(None, use_errno=True).prctl
except (OSError, AttributeError):   # not Linux
    _PRCTL = None


def become_subreaper() -> bool:
    """Make this process its descendants' reaper when their parents end (False where Linux does not offer it)."""
    return _PRCTL is not None and _PRCTL(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0


def resident(pid: int) -> int:
    """Bytes of `pid`'s resident memory (0 once it has ended)."""
    try:
        with open(f'/proc/{pid}/statm', 'rb') as statm:
            return int(statm.read().split()[1]) * PAGE
    except (OSError, IndexError, ValueError):
        return 0


def descendants(root: int) -> dict[int, int]:
    """Every living descendant of `root`, with its resident bytes (one look at each process in /proc)."""
    children: dict[int, list[tuple[int, int]]] = {}
    for name in os.listdir('/proc'):
        if not name.isdigit():
            continue
        try:
            with open(f'/proc/{name}/stat', 'rb') as stat:
                fields = stat.read().rpartition(b')')[2].split()   # after the command name, which may hold spaces
        except OSError:   # it has just ended
            continue
        if len(fields) > 22:
            children.setdefault(int(fields[1]), []).append((int(name), int(fields[21]) * PAGE))
    found: dict[int, int] = {}
    stack = [root]
    while stack:
        for pid, size in children.get(stack.pop(), ()):
            if pid not in found:
                found[pid] = size
                stack.append(pid)
    return found


def end_descendants() -> None:
    """Kill every descendant of this process and reap its children until none is left: the ones whose parents are
    killed come to this process (a subreaper) and are killed and reaped in turn."""
    while True:
        try:
            pid, _ = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return   # no child left: with this process a subreaper, no descendant either
        if pid:
            continue
        for pid in descendants(os.getpid()):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:   # ended meanwhile
                pass
        try:
            os.waitpid(-1, 0)
        except ChildProcessError:
            return
