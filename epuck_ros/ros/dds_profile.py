"""Every process of the package loads one Fast DDS profile file (fastdds_profiles.xml) unless the user chose one.

Why, in short (the file itself has the settings and figures):
- discovery: a participant that misses another's first announcements learns of it only at the next periodic
  announcement, seconds later by default; the profile announces far more often (benchmarks/bench_startup.py);
- acknowledgements: reliable writers send heartbeats far more often than by default and readers answer them at
  once, so a behaviour's last zero command and the simulator's ack window (ros/ack_window.py) are acknowledged
  within milliseconds (benchmarks/bench_lockstep.py);
- liveliness: a participant that stops announcing is dropped within seconds, not tens of seconds;
- the profile of a process that never reads its own topics (fastdds_no_local_profiles.xml, `use_no_local_profile`:
  the simulator and the behaviours) adds that its endpoints never match each other: matching every new one of a
  swarm's thousands against all the others made a big swarm's start-up many times longer, in the simulator and in
  an `avoid --robots all` process alike (benchmarks/bench_swarm_startup.py).

This tuning, the ack window's sizes (Fast DDS's reader limits) and the recorder's take of every message DDS holds
(rclpy's `Subscription.handle.take_message`, pinned by a test in test_bag_record.py) are Fast DDS's and rclpy 7.1's:
`warn_if_not_fast_dds` says so at start under another middleware, in each process this tuning serves: the sim, the
controllers, the recorder and `bringup`. The sim, the controllers and `bringup`'s monitor also spin on rclpy's
experimental EventsExecutor (rclpy 7.1.4 on).
"""
from __future__ import annotations

import os
from pathlib import Path

PROFILES_FILE = Path(__file__).with_name('fastdds_profiles.xml')
NO_LOCAL_PROFILES_FILE = Path(__file__).with_name('fastdds_no_local_profiles.xml')
"""The package's profile plus no matching of a process's own endpoints (the file says why)."""
PROFILES_VARIABLE = 'FASTRTPS_DEFAULT_PROFILES_FILE'


FAST_DDS = 'rmw_fastrtps_cpp'


def warn_if_not_fast_dds(logger: object) -> None:
    """One warning when the middleware is not Fast DDS: the package's timings and limits were measured with it."""
    import rclpy
    found = rclpy.get_rmw_implementation_identifier()
    if found != FAST_DDS:
        logger.warning(f'middleware {found}: epuck_ros is tuned for {FAST_DDS} (its DDS profile, the simulator\'s '
                       f'acknowledgement window, the recorder): runs work, their figures may differ')


def use_package_profile() -> None:
    """Call before `rclpy.init`; the processes this one starts inherit the choice."""
    if PROFILES_FILE.is_file():
        os.environ.setdefault(PROFILES_VARIABLE, str(PROFILES_FILE))


def use_no_local_profile() -> None:
    """The package's profile without matching of this process's own endpoints, for a process that never reads its
    own topics (the simulator, a behaviour), unless the user chose a profile (the package's, which `bringup` sets
    for its children, is no choice of theirs); call before `rclpy.init`."""
    if os.environ.get(PROFILES_VARIABLE) in (None, '', str(PROFILES_FILE)) and NO_LOCAL_PROFILES_FILE.is_file():
        os.environ[PROFILES_VARIABLE] = str(NO_LOCAL_PROFILES_FILE)
