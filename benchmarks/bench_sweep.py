"""How fast trials run headless, against the same trial through ROS, and how a sweep grows with Dask workers.

Measured in one run on this machine:
- one trial (avoid, default world, 1 robot, `--seconds` simulated) through `bringup --lockstep --real-time-factor
  0` (start-up included, wall time of the whole command) and headless (`run_trial`): the ratio per trial;
- a headless trial's speed as a multiple of real time (single core, this process);
- the course's `obstacle_avoidance.py` (a Webots-style script) the same way: through `bringup --controller` and
  headless, in this process (`trial.run`) and as a sweep runs it (`run_trial`: in a forked child, fork included);
- `--trials` such trials as a sweep: in this process (`--workers 0`), then on a local Dask cluster of 1 and of 2
  workers (start-up of the cluster excluded: it is paid once per sweep): trials per second, the speed-up of 2
  workers over 1, and Dask's overhead per trial against the in-process sweep.

Run (ROS_DOMAIN_ID of your own): python benchmarks/bench_sweep.py [--seconds 60] [--trials 200]; `--sweep-only`
runs only the avoid sweeps (in this process, 1 and 2 Dask workers), which give Dask's overhead per trial.
"""
from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from epuck_ros.experiments.cluster import open_client
from epuck_ros.experiments.cli import results
from epuck_ros.experiments.trial import Script, Trial, controller_from, run, run_trial


COURSE_AVOIDANCE = Path(__file__).resolve().parents[1] / 'test' / 'data' / 'course_controllers' / \
    'obstacle_avoidance.py'


def bringup_trial(seconds: float, *controller: str) -> None:
    """A whole `bringup` command (avoid, or `controller`) in lockstep at real_time_factor 0."""
    bringup = shutil.which('bringup') or str(Path(sys.executable).with_name('bringup'))
    subprocess.run([bringup, *(controller or ['avoid']), '--duration', f'{seconds:g}', '--real-time-factor', '0',
                    '--lockstep'], check=True, stdout=subprocess.DEVNULL,
                   env=dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST'))


def cpu_seconds() -> float:
    """CPU time of this process and of every child it has waited for (bringup's own children included)."""
    mine, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return mine.ru_utime + mine.ru_stime + children.ru_utime + children.ru_stime


def best_of(count: int, action: Callable[[], object]) -> tuple[float, float]:
    """The least wall and the least CPU seconds of `count` runs of `action` (other jobs on a shared machine
    lengthen the wall time far more than the CPU time)."""
    walls, cpus = [], []
    for _ in range(count):
        wall, cpu = time.perf_counter(), cpu_seconds()
        action()
        walls.append(time.perf_counter() - wall)
        cpus.append(cpu_seconds() - cpu)
    return min(walls), min(cpus)


def sweep_rate(trials: list[Trial], workers: int) -> float:
    """Trials per wall second of a sweep of `trials` (cluster start-up excluded)."""
    with open_client(workers, None) as client:
        if client is not None:
            client.submit(sum, [1]).result()   # the workers are up
        begin = time.perf_counter()
        for _ in results(client, trials):
            pass
        return len(trials) / (time.perf_counter() - begin)


def best_rates(trials: list[Trial], counts: tuple[int, ...], rounds: int) -> list[float]:
    """The best rate of each worker count over `rounds` rounds, the counts interleaved in each round (other jobs on
    the machine then slow each count alike)."""
    rates = [[sweep_rate(trials, workers) for workers in counts] for _ in range(rounds)]
    return [max(column) for column in zip(*rates)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=60.0, help='simulated seconds per trial (default 60)')
    parser.add_argument('--trials', type=int, default=200, help='trials of the sweep (default 200)')
    parser.add_argument('--rounds', type=int, default=3, help='rounds of the sweeps, best kept (default 3)')
    parser.add_argument('--sweep-only', action='store_true',
                        help='only the avoid sweeps (in this process, 1 and 2 Dask workers): Dask\'s overhead')
    args = parser.parse_args()
    print(f'load average at the start: {os.getloadavg()[0]:.1f} ({os.cpu_count()} cores)')
    run_trial(Trial(controller_from('avoid'), duration=args.seconds, seed=0))   # imports and caches warm
    if not args.sweep_only:
        single_trials(args.seconds)
    avoid_sweeps(args.trials, args.seconds, args.rounds)
    if not args.sweep_only:
        script_sweeps(args.trials // 4, args.seconds, args.rounds)
    print(f'load average at the end: {os.getloadavg()[0]:.1f}')


def single_trials(seconds: float) -> None:
    """One avoid trial and one script trial, through `bringup` and headless."""
    trial = Trial(controller_from('avoid'), duration=seconds, seed=0)
    ros, ros_cpu = best_of(2, lambda: bringup_trial(seconds))
    headless, headless_cpu = best_of(3, lambda: run_trial(trial))
    print(f'one {seconds:g} s avoid trial: bringup {ros:.2f} s wall, {ros_cpu:.2f} s CPU (start-up included, '
          f'all its processes); headless {headless * 1000:.1f} ms wall, {headless_cpu * 1000:.1f} ms CPU: '
          f'{ros / headless:.0f}x faster per trial ({ros_cpu / headless_cpu:.0f}x less CPU); headless runs at '
          f'{seconds / headless:.0f}x real time on one core')
    script = Trial(Script(str(COURSE_AVOIDANCE)), duration=seconds, seed=0)
    script_ros, script_ros_cpu = best_of(2, lambda: bringup_trial(seconds, '--controller',
                                                                  str(COURSE_AVOIDANCE)))
    in_process, in_process_cpu = best_of(5, lambda: run(script))
    isolated, isolated_cpu = best_of(5, lambda: run_trial(script))
    print(f'the course\'s obstacle_avoidance.py for {seconds:g} s: bringup --controller {script_ros:.2f} s '
          f'wall, {script_ros_cpu:.2f} s CPU; headless in this process {in_process * 1000:.1f} ms wall '
          f'({seconds / in_process:.0f}x real time), {in_process_cpu * 1000:.1f} ms CPU '
          f'({seconds / in_process_cpu:.0f}x); as a sweep runs it, in a forked child, {isolated * 1000:.1f} ms '
          f'wall ({seconds / isolated:.0f}x real time, {script_ros / isolated:.0f}x faster than bringup), '
          f'{isolated_cpu * 1000:.1f} ms CPU ({seconds / isolated_cpu:.0f}x)')


def avoid_sweeps(count: int, seconds: float, rounds: int) -> None:
    """`count` avoid trials in this process and on 1 and 2 local Dask workers: the rates, Dask's overhead."""
    trials = [Trial(controller_from('avoid'), duration=seconds, seed=seed, index=seed) for seed in range(count)]
    alone, one, two = best_rates(trials, (0, 1, 2), rounds)
    print(f'{count} avoid trials: in this process {alone:.1f} trials/s; local Dask, 1 worker {one:.1f} '
          f'trials/s, 2 workers {two:.1f} trials/s ({two / one:.2f}x of 1 worker); Dask overhead per trial '
          f'{(1 / one - 1 / alone) * 1000:.2f} ms ({(alone / one - 1) * 100:.1f} % of a trial in this process)')


def script_sweeps(count: int, seconds: float, rounds: int) -> None:
    """`count` obstacle_avoidance.py trials in this process and on 2 local Dask workers."""
    scripts = [Trial(Script(str(COURSE_AVOIDANCE)), duration=seconds, seed=seed, index=seed) for seed in range(count)]
    alone, two = best_rates(scripts, (0, 2), rounds)
    print(f'{len(scripts)} obstacle_avoidance.py trials (each in a forked child): in this process {alone:.1f} '
          f'trials/s, local Dask of 2 workers {two:.1f} trials/s ({two / alone:.2f}x)')


if __name__ == '__main__':
    main()
