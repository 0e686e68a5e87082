"""Private ROS domains on one machine: each holder of a domain keeps a lock file on it for as long as it needs it.

Test runs and simulators started for tests claim their domains here, so that two of them on one machine (parallel
CI jobs, several fixtures) never hear each other's topics.
"""
from __future__ import annotations

import fcntl
import os
from pathlib import Path
from typing import IO

LOCK_DIR = Path('/tmp/epuck_ros_test_domains')
FIRST, COUNT = 10, 90
"""Domains 10..99: valid for DDS on Linux (at most 101) and clear of the default 0."""


def lock_domain(domain: int) -> IO | None:
    """The open lock of `domain` (keep it: closing it frees the domain), None if someone else holds it."""
    LOCK_DIR.mkdir(exist_ok=True)
    handle = open(LOCK_DIR / f'{domain}.lock', 'w')
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        handle.close()
        return None
    return handle


def claim_free_domain() -> tuple[int, IO]:
    """A domain no other holder on this machine has, and its lock."""
    start = os.getpid() % COUNT
    for offset in range(COUNT):
        domain = FIRST + (start + offset) % COUNT
        handle = lock_domain(domain)
        if handle is not None:
            return domain, handle
    raise RuntimeError(f'no free ROS_DOMAIN_ID between {FIRST} and {FIRST + COUNT - 1}')
