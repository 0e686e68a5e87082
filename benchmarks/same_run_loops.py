"""Same seed, same run, many times over (issue 25, point 4): every example script and program of the course on 1
and 3 robots, through `bringup` (lockstep, recorded) `--repeats` times and headless, compared step by step to the
bit; with `--busy` a `while True: pass` loop on every core beside every run; and the 3-script DDS test of
test/test_experiments.py looped `--dds-loops` times under the same load. Prints each run's verdict and the counts.

    python benchmarks/same_run_loops.py                         # (a): every script, 1 and 3 robots, bringup twice
    python benchmarks/same_run_loops.py --busy --rounds 10      # (b): the same with busy loops, 10 rounds
    python benchmarks/same_run_loops.py --busy --rounds 0 --dds-loops 50    # (c)

Run it with the venv's Python and `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST` (scripts/env.sh) on a ROS domain of
your own; it exits 1 if any run differed.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'test'))
from same_run import bringup_truth, difference, example_cases, headless_truth  # noqa: E402

THREE_SCRIPT_TEST = ('test/test_experiments.py::'
                     'test_three_robots_each_driven_by_a_script_over_dds_are_the_headless_trial')


def busy_loops(count: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(count)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--rounds', type=int, default=1, help='passes over every script (default 1)')
    parser.add_argument('--repeats', type=int, default=2, help='bringup runs per script and round (default 2)')
    parser.add_argument('--robots', type=int, nargs='+', default=[1, 3], help='robot counts (default 1 3)')
    parser.add_argument('--duration', type=float, default=3.0, help='simulated seconds per run (default 3)')
    parser.add_argument('--busy', action='store_true', help='a busy loop on every core beside the runs')
    parser.add_argument('--dds-loops', type=int, default=0, help='times to loop the 3-script DDS test (default 0)')
    args = parser.parse_args()
    loops = busy_loops(os.cpu_count() or 1) if args.busy else []
    runs = failures = 0
    began = time.monotonic()
    try:
        for round_ in range(args.rounds):
            for robots in args.robots:
                for case in example_cases(0 if robots == 1 else robots, args.duration):
                    expected = headless_truth(case)
                    for repeat in range(args.repeats):
                        with tempfile.TemporaryDirectory() as scratch:
                            try:
                                got, output = bringup_truth(case, Path(scratch) / 'bag')
                                why = difference(expected, got)
                                if not why and '[bringup] reproducible:' not in output:
                                    why = 'bringup did not say the run was reproducible'
                            except RuntimeError as error:
                                why = str(error).splitlines()[0]
                        runs += 1
                        failures += bool(why)
                        print(f'round {round_ + 1} {case.label} run {repeat + 1}: {why or "equal to the bit"}',
                              flush=True)
        for loop in range(args.dds_loops):
            result = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                                     THREE_SCRIPT_TEST], cwd=ROOT, capture_output=True, text=True)
            runs += 1
            failures += result.returncode != 0
            print(f'3-script DDS test {loop + 1}: {"passed" if result.returncode == 0 else "FAILED"}', flush=True)
            if result.returncode:
                print(result.stdout[-3000:], flush=True)
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
    print(f'{runs} runs, {failures} differed or failed, in {time.monotonic() - began:.0f} s'
          f'{" with a busy loop on every core" if args.busy else ""}')
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
