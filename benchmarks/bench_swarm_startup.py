"""How long `bringup` takes to start a swarm, run it and stop every process, as users start it.

`bringup avoid --robots N --world <a 10 m x 10 m arena> --duration 0.1 --real-time-factor 0` (the built-in 1 m
arena holds about a hundred e-pucks): the simulator, one `avoid --robots all` process driving every robot, and
bringup's own monitor, in lockstep. Timed from the start, by bringup's and the simulator's lines: 'sim ready' (the
simulator made every robot's topics), ready = 'running' (bringup saw every robot's controller connected and resumed
the simulator), the end ('paused at': the simulator reached the duration), and the exit of bringup once every child
stopped (stop = exit - end). A run counts only with exit code 0; the load average is printed with each.

With `--baseline DIR` (a checkout of another commit, e.g. `git archive HEAD~1 | tar -x -C /tmp/base`) each size
runs both, alternating which goes first, `--repeats` times: on a shared machine both see the same load, and the
ratio of the two medians is the figure to compare. Processes are started with PYTHONPATH at the checkout, so each
runs its own code (and its own Fast DDS profile files).

    python benchmarks/bench_swarm_startup.py [--counts 200,500] [--repeats 1] [--baseline /tmp/base]
"""
from __future__ import annotations

import argparse
import math
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
BRINGUP = Path(sys.executable).with_name('bringup')
TIMEOUT = 900.0
"""Wall seconds a run may take before it counts as failed (bringup is sent SIGINT, then killed)."""
PAUSE = 10.0
"""Wall seconds between two runs: longer than the participant lease of the package's DDS profile, so a run does not
meet the last one's processes in the graph."""
LINES = {'sim': 'sim ready', 'ready': '[bringup] running', 'end': 'paused at'}


def run_once(checkout: Path, robots: int, world: Path) -> dict[str, float]:
    """One bringup run from `checkout`: the wall seconds at which each of LINES came, the exit and its code."""
    env = dict(os.environ, PYTHONPATH=str(checkout), PYTHONUNBUFFERED='1')
    started = time.monotonic()
    proc = subprocess.Popen(
        [str(BRINGUP), 'avoid', '--robots', str(robots), '--world', str(world), '--duration', '0.1',
         '--real-time-factor', '0'], cwd=checkout, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, start_new_session=True)
    seen: dict[str, float] = {}
    errors: list[str] = []

    def read_output() -> None:
        for line in proc.stdout:
            for key, text in LINES.items():
                if text in line and key not in seen:
                    seen[key] = time.monotonic() - started
            if '[bringup] error' in line:
                errors.append(line.strip())

    reader = threading.Thread(target=read_output, daemon=True)
    reader.start()
    try:
        code = proc.wait(timeout=TIMEOUT)
    except subprocess.TimeoutExpired:
        proc.send_signal(signal.SIGINT)
        try:
            code = proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            code = proc.wait()
    exited = time.monotonic() - started
    reader.join(timeout=5)
    for error in errors:
        print(f'    {error}', flush=True)
    time.sleep(PAUSE)
    return {key: seen.get(key, math.nan) for key in LINES} | {
        'exit': exited, 'stop': exited - seen.get('end', math.nan), 'code': code}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--counts', default='200,500', help='comma-separated numbers of robots')
    parser.add_argument('--repeats', type=int, default=1)
    parser.add_argument('--baseline', type=Path, help='a checkout to compare with, run alternately')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('ROS_DOMAIN_ID', '142')
    checkouts = {'this': HERE} | ({'baseline': args.baseline.resolve()} if args.baseline else {})
    results: dict[tuple[str, int], list[dict[str, float]]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        world = Path(scratch) / 'arena.yaml'
        world.write_text('arena: {size: [10.0, 10.0]}\n')
        for robots in (int(count) for count in args.counts.split(',')):
            for repeat in range(args.repeats):
                order = list(checkouts) if repeat % 2 == 0 else list(reversed(checkouts))
                for label in order:
                    load = os.getloadavg()[0]
                    result = run_once(checkouts[label], robots, world)
                    results.setdefault((label, robots), []).append(result)
                    print(f'{label:8} {robots:5} robots (load {load:4.1f}): exit code {result["code"]}; sim ready '
                          f'{result["sim"]:6.1f} s, running {result["ready"]:6.1f} s, ended {result["end"]:6.1f} s, '
                          f'all stopped {result["exit"]:6.1f} s (stop {result["stop"]:4.1f} s)', flush=True)
    print('\nmedians of the runs that exited 0:')
    for (label, robots), runs in sorted(results.items(), key=lambda item: (item[0][1], item[0][0])):
        good = [run for run in runs if run['code'] == 0]
        if not good:
            print(f'{label:8} {robots:5} robots: no run exited 0 ({len(runs)} run(s))')
            continue
        ready, total = statistics.median(r['ready'] for r in good), statistics.median(r['exit'] for r in good)
        line = f'{label:8} {robots:5} robots: running after {ready:6.1f} s, all stopped after {total:6.1f} s ' \
               f'({len(good)} of {len(runs)} exited 0)'
        base = [r for r in results.get(('baseline', robots), []) if r['code'] == 0]
        if label == 'this' and base:
            line += f'; baseline/this: running {statistics.median(r["ready"] for r in base) / ready:.2f}x'
        print(line)


if __name__ == '__main__':
    main()
