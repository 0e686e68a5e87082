"""What recording an IR-only run costs: `bringup --controller avoid_obstacles.py --record` (the example Webots script,
which reads only its IR sensors), lockstep, default world, seed 0, at real_time_factor 0 unless told otherwise.

Figures per case: the bag's size and message count, the speed bringup reports (simulated seconds per wall second from
the resume) and the whole command's wall time (start-up and stop included), and the CPU seconds of bringup and its
children. Cases, run alternately `--repeats` times so that all see the same load:
- this checkout as it is: the recorder asks for no sense, so the simulator renders none;
- the same with `-p senses:=camera,ground,light,imu`: every sense computed and recorded, what recording any run cost
  while the recorder's subscription asked the simulator for every sense (bags/webots_avoid: 9.4 MB for 30 s);
- with `--baseline DIR`, a checkout of another commit run the same way, e.g. the one before the simulator had
  senses (main before they were merged): `git archive 259a937^1 | tar -x -C /tmp/before_senses` (processes start
  with PYTHONPATH at the checkout).
The ratios are of the medians, to the baseline (or to the case with every sense when there is none).

    python benchmarks/bench_record.py [--duration 30] [--repeats 3] [--real-time-factor 0] [--baseline DIR]
"""
from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '53')

HERE = Path(__file__).resolve().parents[1]
SCRIPT = HERE / 'epuck_ros' / 'webots' / 'examples' / 'avoid_obstacles.py'
BIN = Path(sys.executable).parent
SPEED = re.compile(r'\[bringup\] simulated ([\d.]+) s in ([\d.]+) s wall \(([\d.]+)x real time\)')
ALL_SENSES = ['-p', 'senses:=camera,ground,light,imu']


def children_cpu() -> float:
    """CPU seconds (user + system) of this process's waited-for children so far."""
    usage = os.times()
    return usage.children_user + usage.children_system


def run_once(checkout: Path, bag: Path, duration: float, rate: float, extra: list[str]) -> dict[str, float]:
    """One recorded run from `checkout`: MB, messages, speed (x real time), wall s, CPU s."""
    env = dict(os.environ, PYTHONPATH=str(checkout))
    cpu, started = children_cpu(), time.monotonic()
    result = subprocess.run([str(BIN / 'bringup'), '--controller', str(SCRIPT), '--duration', f'{duration:g}',
                             '--real-time-factor', f'{rate:g}', '--record', str(bag), *extra],
                            cwd=checkout, env=env, capture_output=True, text=True, timeout=3600)
    wall, cpu = time.monotonic() - started, children_cpu() - cpu
    found = SPEED.search(result.stdout)
    if result.returncode != 0 or not found:
        raise RuntimeError(f'bringup failed ({result.returncode}) from {checkout}:\n{result.stdout[-2000:]}'
                           f'{result.stderr[-2000:]}')
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    size = sum(path.stat().st_size for path in bag.iterdir())
    return {'MB': size / 1e6, 'messages': info['message_count'], 'speed': float(found[3]), 'wall': wall,
            'cpu': cpu}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=30.0, help='simulated seconds per run (default 30)')
    parser.add_argument('--repeats', type=int, default=3, help='runs of each case (default 3)')
    parser.add_argument('--real-time-factor', type=float, default=0.0, help='bringup\'s (default 0: at full speed)')
    parser.add_argument('--baseline', type=Path, help='a checkout of another commit, run alternately')
    options = parser.parse_args()
    cases = {'this checkout': (HERE, []), 'every sense': (HERE, ALL_SENSES)}
    if options.baseline is not None:
        cases['baseline'] = (options.baseline.resolve(), [])
    print(f'{SCRIPT.name} recorded through bringup, {options.duration:g} simulated s, real_time_factor '
          f'{options.real_time_factor:g}; ROS_DOMAIN_ID={os.environ["ROS_DOMAIN_ID"]}, load average '
          f'{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores')
    results: dict[str, list[dict[str, float]]] = {name: [] for name in cases}
    with tempfile.TemporaryDirectory() as folder:
        for repeat in range(options.repeats):
            order = list(cases) if repeat % 2 == 0 else list(reversed(cases))
            for name in order:
                checkout, extra = cases[name]
                bag = Path(folder) / f'{name.replace(" ", "_")}_{repeat}'
                results[name].append(run_once(checkout, bag, options.duration, options.real_time_factor, extra))
    reference = 'baseline' if 'baseline' in results else 'every sense'
    medians = {name: {key: statistics.median(run[key] for run in runs) for key in runs[0]}
               for name, runs in results.items()}
    for name, median in medians.items():
        ratio = '' if name == reference else '; ' + ', '.join(
            f'{key} {median[key] / medians[reference][key]:.2f}x' for key in ('MB', 'speed', 'wall', 'cpu'))
        print(f'  {name:14} {median["MB"]:6.2f} MB, {median["messages"]:7.0f} messages, {median["speed"]:6.1f}x real '
              f'time, {median["wall"]:5.1f} s wall, {median["cpu"]:5.1f} s CPU (medians of {options.repeats})'
              f'{ratio and " vs " + reference + ratio}')


if __name__ == '__main__':
    main()
