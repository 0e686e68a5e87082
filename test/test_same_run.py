"""Same seed, same run (issue 25): every example script and program of the course, through `bringup` in lockstep
(simulator and `webots_controller` over DDS, recorded) and as a headless trial, give the same ground truth at every
step, to the bit, and `bringup` says the run was reproducible. Scripts that read senses (the light seeker, the line
follower, the red-box finder) included: their first readings no longer depend on when discovery delivers a topic.

One pass here: every script that reads a sense on 1 robot and on 3 robots (light, ground, camera, proximity), and
one that only drives (spin.py); the other plain drives (on 1 and on 3 robots: what decides them is the clock and
the wheels, which spin.py's run checks) and the run beside busy loops are the slow tier (marker `slow`:
`scripts/test.sh --slow`, .ci/run). `python benchmarks/same_run_loops.py` repeats it all many times with busy loops
on every core beside it (its figures are in the README)."""
from __future__ import annotations

import subprocess
import sys

import pytest
from conftest import processes_in_this_domain

from same_run import Case, bringup_truth, difference, example_cases, headless_truth

SENSES_OF_EACH_KIND = ('light_seeker.py', 'line_follower.py', 'find_red_box.py', 'obstacle_avoidance.py')
"""The scripts whose 3-robot runs stay in the quick tier: light, ground, camera and proximity, read from the first
step by each robot's own webots_controller; 3 robots of the other scripts add little but time."""
PLAIN_DRIVES = ('circle.py', 'straight_line.py', 'timed_rectangle.py', 'circular_and_turn_around.py', 'controller_1.py',
                'controller_4.py')
"""Scripts that enable no sensor: one robot of each is in the slow tier, spin.py's stays here for them all."""
CASES = [*example_cases(robots=0, duration=3.0), *example_cases(robots=3, duration=2.0)]


def _quick(case: Case) -> bool:
    script = case.label.split()[0]
    return script in SENSES_OF_EACH_KIND if case.robots else script not in PLAIN_DRIVES


PARAMS = [pytest.param(case, id=case.label, marks=() if _quick(case) else pytest.mark.slow) for case in CASES]


@pytest.mark.parametrize('case', PARAMS)
def test_a_script_through_bringup_is_its_headless_trial_to_the_bit(case: Case, tmp_path) -> None:
    expected = headless_truth(case)
    got, output = bringup_truth(case, tmp_path / 'bag')
    assert difference(expected, got) == '', output
    assert '[bringup] reproducible: every step was answered' in output, output
    assert processes_in_this_domain() == []


@pytest.mark.slow   # takes both cores from the rest of the suite for the whole run
def test_the_same_run_beside_busy_loops_on_every_core(tmp_path) -> None:
    """The light seeker (camera-free, light sensors from its first step) with `while True: pass` on both cores."""
    case = Case(str(next(c.controller for c in CASES if c.controller.endswith('light_seeker.py'))), duration=3.0)
    loops = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(2)]
    try:
        got, output = bringup_truth(case, tmp_path / 'bag')
    finally:
        for loop in loops:
            loop.kill()
            loop.wait()
    assert difference(headless_truth(case), got) == '', output
