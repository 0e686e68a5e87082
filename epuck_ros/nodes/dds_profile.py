"""Every process of the package loads one Fast DDS profile file (fastdds_profiles.xml) unless the user chose one.

Why, in short (the file itself has the figures):
- discovery: a participant that misses another's first announcements (about half of the starts on these
  machines) learns of it only at the next periodic announcement, 3 s later by default; every 0.5 s instead
  (benchmarks/bench_startup.py);
- acknowledgements: reliable writers send a heartbeat every 50 ms instead of 3 s and readers answer it at once,
  so a behaviour's last zero command and the simulator's ack window (nodes/ack_window.py) are acknowledged
  within milliseconds (benchmarks/bench_lockstep.py).
"""
from __future__ import annotations

import os
from pathlib import Path

PROFILES_FILE = Path(__file__).with_name('fastdds_profiles.xml')
PROFILES_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'


def use_package_profile() -> None:
    """Call before `rclpy.init`; the processes this one starts inherit the choice."""
    if PROFILES_FILE.is_file():
        os.environ.setdefault(PROFILES_VARIABLE, str(PROFILES_FILE))
