"""How long a swarm's simulator takes to be ready, its memory then, and how long SIGTERM takes to end it.

`sim --ros-args -p robots:=N -p real_time_factor:=0` in a 10 m x 10 m arena (the built-in 1 m one holds about a
hundred e-pucks), started as users start it. Ready: the simulator's `step` service is in the graph of an observer
node in this process (the moment a client could use it); its own 'sim ready' line is timed too. Memory: the
process's resident set once ready. Then SIGTERM, and the time until the process has ended.

With `--baseline DIR` (a checkout of another commit, e.g. `git archive HEAD~1 | tar -x -C /tmp/base`) each size
runs both, alternating which goes first, `--repeats` times: on a shared machine both see the same load, and the
ratio of the two medians is the figure to compare. Processes are started with PYTHONPATH at the checkout, so each
runs its own code (and its own Fast DDS profile files).

    python benchmarks/bench_swarm_startup.py [--counts 1000,2000] [--repeats 2] [--baseline /tmp/base]
"""
from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
os.environ.setdefault('ROS_DOMAIN_ID', '142')

import rclpy  # noqa: E402
from rclpy.context import Context  # noqa: E402
from rclpy.node import Node  # noqa: E402

from epuck_ros.nodes.dds_profile import use_package_profile  # noqa: E402

HERE = Path(__file__).resolve().parents[1]
TIMEOUT = 300.0
"""Wall seconds a simulator may take to be ready before the run counts as failed (and the process is killed)."""


def resident_mib(pid: int) -> float:
    with open(f'/proc/{pid}/status') as status:
        for line in status:
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024
    return float('nan')


def run_once(observer: Node, checkout: Path, robots: int, world: Path) -> dict[str, float]:
    """One simulator of `robots` robots from `checkout`: seconds to ready (graph, log line), MiB, seconds to stop."""
    env = dict(os.environ, PYTHONPATH=str(checkout))
    started = time.monotonic()
    proc = subprocess.Popen(
        [sys.executable, '-m', 'epuck_ros.nodes.sim_node', '--ros-args', '-p', f'robots:={robots}',
         '-p', 'real_time_factor:=0', '-p', f'world:={world}'],
        cwd=checkout, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    said_ready: list[float] = []

    def read_log() -> None:
        for line in proc.stderr:
            if 'sim ready' in line and not said_ready:
                said_ready.append(time.monotonic() - started)

    reader = threading.Thread(target=read_log, daemon=True)
    reader.start()
    ready = None
    try:
        while time.monotonic() - started < TIMEOUT and proc.poll() is None:
            if any(name == '/step' for name, _ in observer.get_service_names_and_types()):
                ready = time.monotonic() - started
                break
            time.sleep(0.05)
        memory = resident_mib(proc.pid) if ready is not None else float('nan')
    finally:
        stopping = time.monotonic()
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
        stop = time.monotonic() - stopping
        reader.join(timeout=5)
    # the next simulator must not meet this one's participant in the graph (its lease: fastdds_profiles.xml)
    time.sleep(3.0)
    return {'ready': float('nan') if ready is None else ready,
            'log': said_ready[0] if said_ready else float('nan'), 'rss': memory, 'stop': stop}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--counts', default='1000,2000', help='comma-separated numbers of robots')
    parser.add_argument('--repeats', type=int, default=2)
    parser.add_argument('--baseline', type=Path, help='a checkout to compare with, run alternately')
    args = parser.parse_args()
    checkouts = {'this': HERE} | ({'baseline': args.baseline.resolve()} if args.baseline else {})
    use_package_profile()
    context = Context()
    rclpy.init(context=context)
    observer = Node('swarm_startup_observer', context=context)
    results: dict[tuple[str, int], list[dict[str, float]]] = {}
    with tempfile.TemporaryDirectory() as scratch:
        world = Path(scratch) / 'arena.yaml'
        world.write_text('arena: {size: [10.0, 10.0]}\n')
        try:
            for robots in (int(count) for count in args.counts.split(',')):
                for repeat in range(args.repeats):
                    order = list(checkouts) if repeat % 2 == 0 else list(reversed(checkouts))
                    for label in order:
                        result = run_once(observer, checkouts[label], robots, world)
                        results.setdefault((label, robots), []).append(result)
                        print(f'{label:8} {robots:6} robots: ready {result["ready"]:6.2f} s (log line '
                              f'{result["log"]:6.2f} s), {result["rss"]:6.0f} MiB, stopped in {result["stop"]:.2f} s',
                              flush=True)
        finally:
            observer.destroy_node()
            rclpy.try_shutdown(context=context)
    print('\nmedians:')
    for (label, robots), runs in sorted(results.items(), key=lambda item: (item[0][1], item[0][0])):
        ready = statistics.median(run['ready'] for run in runs)
        rss = statistics.median(run['rss'] for run in runs)
        line = f'{label:8} {robots:6} robots: ready {ready:6.2f} s, {rss:6.0f} MiB'
        if label == 'this' and ('baseline', robots) in results:
            base = results[('baseline', robots)]
            line += (f'; baseline/this: ready {statistics.median(r["ready"] for r in base) / ready:.2f}x, '
                     f'memory {statistics.median(r["rss"] for r in base) / rss:.2f}x')
        print(line)


if __name__ == '__main__':
    main()
