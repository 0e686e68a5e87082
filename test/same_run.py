"""Same seed, same run, checked: a controller through `bringup` (lockstep, recorded) and as a headless trial, every
step's ground truth compared to the bit. Used by test/test_same_run.py (one pass over every example) and by
benchmarks/same_run_loops.py (the same many times, with busy loops on every core beside it).
"""
from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / 'epuck_ros' / 'webots' / 'examples'
COURSE = ROOT / 'test' / 'data' / 'course_controllers'
WORLDS = ROOT / 'epuck_ros' / 'worlds'
SCRIPT_WORLDS = {'light_seeker.py': 'lit_arena.yaml', 'line_follower.py': 'line_track.yaml',
                 'line_demo.py': 'line_track.yaml', 'find_red_box.py': 'coloured_objects.yaml'}
"""The world each example is written for (its docstring says so); the others run in the default arena."""
BIN = Path(sys.executable).parent


@dataclass(frozen=True)
class Case:
    """One run: a Webots-style script or a behaviour, on a world, with robots (0: the world's), seed, duration."""

    controller: str
    """A script's path, or a behaviour's name."""
    robots: int = 0
    seed: int = 3
    duration: float = 4.0

    @property
    def is_script(self) -> bool:
        return self.controller.endswith('.py')

    @property
    def world(self) -> str | None:
        name = SCRIPT_WORLDS.get(Path(self.controller).name)
        return str(WORLDS / name) if name else None

    @property
    def label(self) -> str:
        return f'{Path(self.controller).name} x{max(self.robots, 1)}'


def example_cases(robots: int, duration: float = 4.0) -> list[Case]:
    """Every example script and every program of the course, on `robots` robots."""
    scripts = sorted(EXAMPLES.glob('*.py')) + sorted(COURSE.glob('*.py'))
    return [Case(str(script), robots, duration=duration) for script in scripts]


def headless_truth(case: Case) -> np.ndarray:
    """Every step's true (x, y) of each robot, (steps, robots, 2), of the headless trial of `case`."""
    from epuck_ros.experiments.trial import Script, Trial, controller_from, run
    controller = Script(case.controller) if case.is_script else controller_from(case.controller)
    poses: list[np.ndarray] = []
    path_before = list(sys.path)
    try:
        run(Trial(controller, world=case.world or 'default', robots=case.robots, seed=case.seed,
                  duration=case.duration), each_step=lambda sim: poses.append(sim.true_pose[:, :2].copy()))
    finally:   # a script's shim sits on sys.path while it runs: taken off again
        sys.path[:] = path_before
        for module in [name for name in sys.modules if name == 'controller' or name.startswith('controller.')]:
            del sys.modules[module]
    return np.array(poses)


def bringup_command(case: Case, bag: Path) -> list[str]:
    """`bringup` of `case` in lockstep as fast as it goes, recorded to `bag`."""
    chosen = ['--controller', case.controller] if case.is_script else [case.controller]
    return [str(BIN / 'bringup'), *chosen, '--lockstep', '--real-time-factor', '0', '--seed', str(case.seed),
            '--duration', f'{case.duration:g}', *(['--robots', str(case.robots)] if case.robots else []),
            *(['--world', case.world] if case.world else []), '--record', str(bag)]


def bringup_truth(case: Case, bag: Path, env: dict[str, str] | None = None, timeout: float = 300.0
                  ) -> tuple[np.ndarray, str]:
    """Every step's true (x, y) of each robot from the bag of a `bringup` run of `case`, and its output (the
    summary says whether the run was reproducible). RuntimeError if bringup failed."""
    from epuck_ros.bag.reader import Bag
    from epuck_ros.bag.runs import load_runs
    result = subprocess.run(bringup_command(case, bag), capture_output=True, text=True, timeout=timeout,
                            env=env or dict(os.environ), stdin=subprocess.DEVNULL)
    output = result.stdout + result.stderr
    if result.returncode != 0:
        raise RuntimeError(f'bringup of {case.label} exited {result.returncode}:\n{output[-3000:]}')
    with Bag(bag) as reader:
        runs = load_runs(reader)
    return np.stack([np.stack([run.truth.x, run.truth.y], axis=1) for run in runs], axis=1), output


def difference(expected: np.ndarray, got: np.ndarray) -> str:
    """'' when the two (steps, robots, 2) ground truths are equal to the bit, else where they first differ."""
    if expected.shape != got.shape:
        return f'{got.shape[0]} steps of {got.shape[1]} robots instead of {expected.shape[0]} of {expected.shape[1]}'
    differs = np.flatnonzero(np.any(expected != got, axis=(1, 2)))
    if not differs.size:
        return ''
    step = int(differs[0])
    return f'first difference at step {step} (t={(step + 1) * 0.032:.3f} s): {got[step].tolist()} instead of ' \
           f'{expected[step].tolist()}'
