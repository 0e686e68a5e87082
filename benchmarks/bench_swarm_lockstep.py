"""A swarm in lockstep through `bringup`, as users run it: this code against a baseline commit, alternating.

`bringup avoid --robots N --duration D --real-time-factor 0 --seed 1` (from 200 robots in a 10 m x 10 m arena, as
issue 34 measured; below, the built-in 1 m arena): the simulator, one `avoid --robots all` process, bringup's
monitor. Printed per run: the real-time factor from the first step to the last (bringup's second figure) and from
the resume, when the first step came after the start (bringup's line that it resumed the simulator, plus the delay
it reports), when bringup and every process had ended, the CPU seconds of bringup and all its processes, whether
bringup said the run was reproducible, and whether every robot's figures (distance,
contacts, the shape driven) equal the other checkout's of the same run (the same seed: the same run, to the bit,
whichever way the robots talk to the simulator), and to the headless trial's (`experiments.trial.run` of the same
world, robots, seed and duration in this process, its lines printed by bringup's own `format_figures`: a robot whose
run differed by one bit anywhere would, with contacts among hundreds of robots, differ in its figures). Then the
medians and the ratio this / baseline.

The baseline is a commit of this repository (`--baseline-rev`, default the one before the swarm topics), unpacked
with `git archive` into a temporary directory; processes run with PYTHONPATH at each checkout, so each runs its own
code. Runs alternate which checkout goes first; each run uses ROS_DOMAIN_ID or ROS_DOMAIN_ID + 1 in turn (a run's
participants linger in the other's graph until their lease ends), or the domains `--domains` names; with one, each
run waits LEASE after the one before.

    ROS_DOMAIN_ID=66 python benchmarks/bench_swarm_lockstep.py [--counts 1,50,200] [--duration 10] [--repeats 1]
        [--domains 66]
"""
from __future__ import annotations

import argparse
import math
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]
BRINGUP = Path(sys.executable).with_name('bringup')
BASELINE_REV = '278215b'
"""main before the swarm topics (issue 34)."""
ARENA_FROM = 200
"""Robots from which the run is in a 10 m x 10 m arena (the built-in 1 m one holds about a hundred e-pucks)."""
TIMEOUT = 1800.0
LEASE = 7.0
"""Wall seconds a run's participants may linger in the graph after it (the package's DDS lease, 6 s, and a margin):
with one domain, the next run waits so long."""
SPEED = re.compile(r'\[bringup\] simulated ([\d.]+) s in ([\d.]+) s wall \(([\d.]+)x real time\); ([\d.]+)x real time '
                   r'from the first step, which came ([\d.]+) s after the resume')
FIGURES = re.compile(r'^\[bringup\] (?!simulated|running|reproducible|note|ROS)(.*)$', re.MULTILINE)
"""bringup's lines of what the robots did (each robot's distance, contacts and shape)."""


def unpack(rev: str, into: Path) -> Path:
    into.mkdir()
    archive = subprocess.run(['git', '-C', str(HERE), 'archive', rev], check=True, capture_output=True).stdout
    subprocess.run(['tar', '-x', '-C', str(into)], input=archive, check=True)
    return into


def run_once(checkout: Path, robots: int, duration: float, world: Path | None, domain: int) -> dict:
    env = dict(os.environ, PYTHONPATH=str(checkout), PYTHONUNBUFFERED='1', ROS_DOMAIN_ID=str(domain))
    command = [str(BRINGUP), 'avoid', '--robots', str(robots), '--duration', str(duration), '--real-time-factor',
               '0', '--seed', '1'] + (['--world', str(world)] if world is not None else [])
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.monotonic()
    proc = subprocess.Popen(command, cwd=checkout, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    lines, resumed = [], math.nan
    for line in proc.stdout:   # bringup says it resumed the simulator: the first step comes right after
        if math.isnan(resumed) and line.startswith('[bringup] running'):
            resumed = time.monotonic() - started
        lines.append(line)
    code = proc.wait(timeout=TIMEOUT)
    wall = time.monotonic() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    output = ''.join(lines)
    speed = SPEED.search(output)
    result = {'code': code, 'wall': wall, 'cpu': cpu, 'rtf': math.nan, 'rtf_resume': math.nan,
              'first': math.nan, 'sim': math.nan, 'figures': FIGURES.findall(output),
              'reproducible': '[bringup] reproducible' in output}
    if speed:
        result.update(sim=float(speed[1]), rtf_resume=float(speed[3]), rtf=float(speed[4]),
                      first=resumed + float(speed[5]))
    if code:
        print('    ' + '\n    '.join(output.strip().splitlines()[-5:]), flush=True)
    return result


ROBOT_LINE = re.compile(r'^\[bringup\] (epuck\d+: .*)$', re.MULTILINE)


def headless_lines(robots: int, duration: float, world: Path | None) -> set[str]:
    """Each robot's summary line of the headless trial of the run (as bringup prints them)."""
    from epuck_ros.bag.summary_text import format_figures
    from epuck_ros.experiments.trial import Trial, controller_from, run
    _, tally = run(Trial(controller_from('avoid'), world=str(world) if world else 'default', robots=robots, seed=1,
                         duration=duration))
    return set(format_figures(tally.figures).splitlines())


def arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--counts', default='1,50,200', help='comma-separated numbers of robots')
    parser.add_argument('--duration', type=float, default=10.0, help='simulated seconds per run')
    parser.add_argument('--repeats', type=int, default=1)
    parser.add_argument('--baseline-rev', default=BASELINE_REV, help='the commit to compare with ("" for none)')
    parser.add_argument('--domains', default='', help='comma-separated ROS domains the runs take in turn (default: '
                                                      'ROS_DOMAIN_ID and the next); one: each run waits LEASE')
    return parser.parse_args()


def main() -> None:
    args = arguments()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    domain = int(os.environ.setdefault('ROS_DOMAIN_ID', '66'))
    domains = [int(d) for d in args.domains.split(',')] if args.domains else [domain, domain + 1]
    results: dict[tuple[str, int], list[dict]] = {}
    runs = 0
    with tempfile.TemporaryDirectory() as scratch:
        world = Path(scratch) / 'arena.yaml'
        world.write_text('arena: {size: [10.0, 10.0]}\n')
        checkouts = {'this': HERE}
        if args.baseline_rev:
            checkouts['baseline'] = unpack(args.baseline_rev, Path(scratch) / 'baseline')
        for robots in (int(count) for count in args.counts.split(',')):
            for repeat in range(args.repeats):
                order = list(checkouts) if repeat % 2 == 0 else list(reversed(checkouts))
                figures = {}
                started = time.monotonic()
                expected = headless_lines(robots, args.duration, world if robots >= ARENA_FROM else None) \
                    if robots > 1 else None
                headless_wall = time.monotonic() - started
                for label in order:
                    if runs and len(domains) == 1:
                        time.sleep(LEASE)
                    load = os.getloadavg()[0]
                    result = run_once(checkouts[label], robots, args.duration,
                                      world if robots >= ARENA_FROM else None, domains[runs % len(domains)])
                    runs += 1
                    results.setdefault((label, robots), []).append(result)
                    figures[label] = result['figures']
                    if expected is not None:
                        got = set(ROBOT_LINE.findall('\n'.join(f'[bringup] {line}' for line in result['figures'])))
                        print(f'{"":8} {robots:5} robots: {label}\'s figures equal the headless trial\'s '
                              f'({headless_wall:.1f} s wall, start-up included) for every robot: '
                              f'{"yes" if got == expected else f"NO ({len(got ^ expected)} lines differ)"}',
                              flush=True)
                    print(f'{label:8} {robots:5} robots (load {load:4.1f}): exit {result["code"]}, '
                          f'{result["rtf"]:6.1f}x real time from the first step ({result["rtf_resume"]:6.1f}x from '
                          f'the resume), first step {result["first"]:5.1f} s after the start, every process ended '
                          f'{result["wall"]:6.1f} s after it, CPU of all processes {result["cpu"]:6.1f} s, '
                          f'reproducible: {"yes" if result["reproducible"] else "NO"}', flush=True)
                if len(figures) == 2:
                    same = figures['this'] == figures['baseline'] and len(figures['this']) >= 1
                    print(f'{"":8} {robots:5} robots: every robot\'s figures equal in both runs: '
                          f'{"yes" if same else "NO"}', flush=True)
    print_medians(results)


def print_medians(results: dict[tuple[str, int], list[dict]]) -> None:
    print('\nmedians of the runs that exited 0:')
    for (label, robots), found in sorted(results.items(), key=lambda item: (item[0][1], item[0][0] != 'this')):
        good = [r for r in found if r['code'] == 0]
        if not good:
            print(f'{label:8} {robots:5} robots: no run exited 0')
            continue
        rtf = statistics.median(r['rtf'] for r in good)
        line = f'{label:8} {robots:5} robots: {rtf:6.1f}x real time ({len(good)} of {len(found)} runs)'
        base = [r for r in results.get(('baseline', robots), []) if r['code'] == 0]
        if label == 'this' and base:
            line += f'; this / baseline: {rtf / statistics.median(r["rtf"] for r in base):.2f}x'
        print(line)


if __name__ == '__main__':
    main()
