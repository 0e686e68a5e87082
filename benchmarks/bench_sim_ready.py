"""How long `sim` alone takes to be ready with N robots, and its memory per robot: this code against a baseline commit.

`sim --ros-args -p robots:=N -p world:=<a 10 m x 10 m arena> -p paused:=true`, timed from the start to its
'sim ready' line (every robot's ports made), its resident memory read there (/proc), then stopped with SIGINT.
Runs alternate between this checkout and `--baseline-rev` (unpacked with `git archive`), each on ROS_DOMAIN_ID and
ROS_DOMAIN_ID + 1 in turn.

    ROS_DOMAIN_ID=66 python benchmarks/bench_sim_ready.py [--counts 2000] [--repeats 1] [--baseline-rev REV]
"""
from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_swarm_lockstep import BASELINE_REV, HERE, unpack

SIM = Path(sys.executable).with_name('sim')
TIMEOUT = 300.0


def ready_once(checkout: Path, robots: int, world: Path, domain: int) -> tuple[float, float]:
    """(wall seconds to 'sim ready', resident MiB then)."""
    env = dict(os.environ, PYTHONPATH=str(checkout), PYTHONUNBUFFERED='1', ROS_DOMAIN_ID=str(domain))
    started = time.monotonic()
    proc = subprocess.Popen([str(SIM), '--ros-args', '-p', f'robots:={robots}', '-p', f'world:={world}', '-p',
                             'paused:=true'], cwd=checkout, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    try:
        for line in proc.stdout:
            if 'sim ready' in line:
                wall = time.monotonic() - started
                rss = int(Path(f'/proc/{proc.pid}/statm').read_text().split()[1]) * os.sysconf('SC_PAGE_SIZE')
                return wall, rss / 2**20
            if time.monotonic() - started > TIMEOUT:
                break
        raise SystemExit(f'bench_sim_ready: no "sim ready" from {checkout}')
    finally:
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--counts', default='2000')
    parser.add_argument('--repeats', type=int, default=1)
    parser.add_argument('--baseline-rev', default=BASELINE_REV, help='the commit to compare with ("" for none)')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    domain = int(os.environ.setdefault('ROS_DOMAIN_ID', '66'))
    runs = 0
    with tempfile.TemporaryDirectory() as scratch:
        world = Path(scratch) / 'arena.yaml'
        world.write_text('arena: {size: [10.0, 10.0]}\n')
        checkouts = {'this': HERE}
        if args.baseline_rev:
            checkouts['baseline'] = unpack(args.baseline_rev, Path(scratch) / 'baseline')
        for robots in (int(count) for count in args.counts.split(',')):
            walls: dict[str, list[float]] = {}
            for repeat in range(args.repeats):
                for label in (list(checkouts) if repeat % 2 == 0 else list(reversed(checkouts))):
                    load = os.getloadavg()[0]
                    wall, rss = ready_once(checkouts[label], robots, world, domain + runs % 2)
                    runs += 1
                    walls.setdefault(label, []).append(wall)
                    print(f'{label:8} {robots:5} robots (load {load:4.1f}): ready after {wall:5.1f} s, resident '
                          f'{rss:6.0f} MiB ({rss * 1024 / robots:5.0f} KiB per robot)', flush=True)
            if 'baseline' in walls:
                ratio = statistics.median(walls['baseline']) / statistics.median(walls['this'])
                print(f'{"":8} {robots:5} robots: baseline / this (ready time, medians): {ratio:.2f}x', flush=True)


if __name__ == '__main__':
    main()
