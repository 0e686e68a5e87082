"""Every process of the package loads one Fast DDS profile file (fastdds_profiles.xml) unless the user chose one.

Why: discovery. A participant that misses another's first announcements (it happens in about half of the starts
on these machines) only learns of it at the next periodic announcement, 3 s later by default; `bringup` then
saw its children 2.5-3.5 s after they were up. The profile announces every 0.5 s instead, and reliable writers
send a heartbeat every 50 ms instead of 3 s, so a reader that missed a message asks for it again at once.
Measured with benchmarks/bench_startup.py.
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
