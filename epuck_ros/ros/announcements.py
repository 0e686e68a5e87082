"""Simulators announce themselves on one latched topic, so any two that hear each other, however late discovery
is, agree on which started first (the later one refuses to run), and `bringup` can tell its own simulator from
another one even when both are nodes called `sim` in the same namespace."""
from __future__ import annotations

import socket
import time
from typing import NamedTuple


SIMULATORS_TOPIC = '/simulators'
"""Latched: every simulator publishes one announcement there when it starts."""


class Announcement(NamedTuple):
    """One simulator process: ordered by wall start time (then pid and host, to break ties)."""

    started_ns: int
    pid: int
    host: str

    def text(self) -> str:
        return f'{self.started_ns} pid {self.pid} on {self.host}'

    def describe(self) -> str:
        """Who it is, for a person: pid, host and local start time (a node not yet known by name has no better)."""
        started = time.strftime('%Y-%m-%d %H:%M:%S', time.localtime(self.started_ns * 1e-9))
        return f'the simulator pid {self.pid} on {self.host}, started {started}'

    def is_process(self, pid: int) -> bool:
        """This announcement is that of process `pid` on this machine."""
        return self.pid == pid and self.host == socket.gethostname()


def announcement(started_ns: int, pid: int) -> Announcement:
    return Announcement(started_ns, pid, socket.gethostname())


def parse_announcement(text: str) -> Announcement | None:
    """The announcement in `text`, or None if it is not one of ours."""
    parts = text.split(' ')
    if len(parts) != 5 or parts[1] != 'pid' or parts[3] != 'on':
        return None
    try:
        return Announcement(int(parts[0]), int(parts[2]), parts[4])
    except ValueError:
        return None
