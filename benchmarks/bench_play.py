"""`bag play` pacing: the wall time a replay takes at several rates, against the bag's own duration / rate.

    python benchmarks/bench_play.py [--bag bags/spin] [--rates 1 2 4 8]

Each rate runs `bag play` as users do (its own process, on a private ROS domain); the player reports the
wall time from its first message to its last acknowledged one. A figure, never an assertion: the tests
check the schedule itself (`epuck_ros.bag.play.schedule`).
"""
from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
from pathlib import Path

from epuck_ros.bag.play import CLOCK_TOPIC
from epuck_ros.bag.reader import Bag

BIN = Path(sys.executable).parent
PLAYED = re.compile(r'played (\d+) messages in ([0-9.]+) s')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--bag', type=Path, default=Path(__file__).resolve().parents[1] / 'bags' / 'spin')
    parser.add_argument('--rates', type=float, nargs='+', default=[1.0, 2.0, 4.0, 8.0])
    args = parser.parse_args()
    with Bag(args.bag) as bag:
        topics = [t for name, t in bag.topics.items() if name != CLOCK_TOPIC and t.message_count]
        seconds = (max(t.last_ns for t in topics) - min(t.first_ns for t in topics)) * 1e-9
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', str(100 + os.getpid() % 100)))
    print(f'bag play {args.bag} ({seconds:.3f} s of messages), ROS_DOMAIN_ID={env["ROS_DOMAIN_ID"]}')
    print(f'{"rate":>6} {"messages":>9} {"wall s":>8} {"expected s":>11} {"wall/expected":>14}')
    for rate in args.rates:
        result = subprocess.run([str(BIN / 'bag'), 'play', str(args.bag), '--rate', str(rate)], env=env,
                                capture_output=True, text=True, timeout=600)
        found = PLAYED.search(result.stdout + result.stderr)
        if result.returncode != 0 or found is None:
            print(f'{rate:>6g} failed (exit {result.returncode}): {result.stderr.strip()[-300:]}')
            continue
        count, wall = int(found.group(1)), float(found.group(2))
        expected = seconds / rate
        print(f'{rate:>6g} {count:>9,} {wall:>8.3f} {expected:>11.3f} {wall / expected:>14.3f}')


if __name__ == '__main__':
    main()
