"""`python -m epuck_ros.bringup.watchdog GRACE`: stops `bringup`'s children if `bringup` dies.

Reads `PID START_TIME` lines on stdin, one per child. A `done` line means `bringup` stopped them
itself: exit. End of input without it means `bringup` is gone (even by SIGKILL, the kernel closes
its end of the pipe): SIGTERM every child still alive (pid and start time must both match, so a
reused pid is never hit), wait up to GRACE seconds, then SIGKILL the rest. No ROS here: it must
start fast and never be the one that hangs.
"""
from __future__ import annotations

import os
import signal
import sys
import time

from epuck_ros.bringup.processes import process_start_time

POLL = 0.05


def alive(children: dict[int, str]) -> dict[int, str]:
    return {pid: start for pid, start in children.items() if process_start_time(pid) == start}


def signal_all(children: dict[int, str], signum: int) -> None:
    for pid in alive(children):
        try:
            os.kill(pid, signum)
        except ProcessLookupError:
            pass


def main() -> None:
    grace = float(sys.argv[1])
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # only the pipe tells this process what to do
    children: dict[int, str] = {}
    for line in sys.stdin:
        if line.strip() == 'done':
            return
        pid, start = line.split()
        children[int(pid)] = start
    signal_all(children, signal.SIGTERM)
    deadline = time.monotonic() + grace
    while alive(children) and time.monotonic() < deadline:
        time.sleep(POLL)
    signal_all(children, signal.SIGKILL)


if __name__ == '__main__':
    main()
