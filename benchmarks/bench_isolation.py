"""What a script trial's isolation costs: the course's obstacle_avoidance.py run headless in this process (`run`)
and as a sweep runs it (`run_trial`: a forked child under a keeper that watches its time and memory and ends every
process it started), best of --repeats, alternating; the ratio of the two is the isolation's cost per trial.

Run: python benchmarks/bench_isolation.py [--seconds 60] [--repeats 7]. Wall and CPU (this process and every
child waited for, the keeper and the trial's process included).
"""
from __future__ import annotations

import argparse
import resource
import time
from pathlib import Path

from epuck_ros.experiments.trial import Script, Trial, run, run_trial

COURSE_AVOIDANCE = Path(__file__).resolve().parents[1] / 'test' / 'data' / 'course_controllers' / \
    'obstacle_avoidance.py'


def cpu_seconds() -> float:
    mine, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return mine.ru_utime + mine.ru_stime + children.ru_utime + children.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--seconds', type=float, default=60.0, help='simulated seconds per trial (default 60)')
    parser.add_argument('--repeats', type=int, default=7, help='runs of each, alternating (default 7)')
    args = parser.parse_args()
    trial = Trial(Script(str(COURSE_AVOIDANCE)), duration=args.seconds, seed=0)
    run_trial(trial)   # imports and first-use costs out of the figures
    figures: dict[str, list[tuple[float, float]]] = {'in this process': [], 'isolated': []}
    for _ in range(args.repeats):
        for name, action in (('in this process', lambda: run(trial)), ('isolated', lambda: run_trial(trial))):
            wall, cpu = time.perf_counter(), cpu_seconds()
            action()
            figures[name].append((time.perf_counter() - wall, cpu_seconds() - cpu))
    best = {name: (min(wall for wall, _ in runs), min(cpu for _, cpu in runs)) for name, runs in figures.items()}
    for name, (wall, cpu) in best.items():
        print(f'{name}: {wall * 1000:.1f} ms wall, {cpu * 1000:.1f} ms CPU (best of {args.repeats})')
    (wall, cpu), (base_wall, base_cpu) = best['isolated'], best['in this process']
    print(f'isolation: {(wall - base_wall) * 1000:+.1f} ms wall ({wall / base_wall:.2f}x), '
          f'{(cpu - base_cpu) * 1000:+.1f} ms CPU ({cpu / base_cpu:.2f}x) per trial')


if __name__ == '__main__':
    main()
