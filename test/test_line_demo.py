"""Webots' line demo, retold in Python with its own thresholds (white above 800, the line below 500), follows the
shipped line track unchanged: a whole lap headless, and half a lap over ROS through `bringup` in lockstep.

Before the ground sensors were placed and lit as Webots' (3.3 mm above a floor of roughness 0.2), white read 987
and the line 934: the demo drove off the track into a wall and `line_follower.py` with those thresholds turned on
the spot."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from conftest import processes_in_this_domain
from epuck_ros.experiments.trial import Script, Trial, run
from epuck_ros.world import load_world

EXAMPLES = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples'
TRACK = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds' / 'line_track.yaml'
LAP = 80.0
"""Simulated seconds: the demo's 200 steps/s (0.025 m/s) take 76 s round the 1.9 m oval."""
NEAR_LINE = 0.004
"""m: the robot's centre never farther than this from the line's middle (the line is 25 mm wide)."""


def off_line(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distance (m) of each point to the middle of the track's painted line (its polyline)."""
    line = np.array(load_world(TRACK).appearance.paint[0].points)
    start, along = line[:-1], np.diff(line, axis=0)
    points = np.column_stack([x, y])[:, None, :]
    share = np.clip(((points - start) * along).sum(-1) / (along * along).sum(-1), 0.0, 1.0)
    return np.hypot(*(points - start - share[..., None] * along).transpose(2, 0, 1)).min(axis=1)


def laps(x: np.ndarray, y: np.ndarray) -> float:
    """Turns round the oval's centre (0.7 x 0.5 m), counted on the unwrapped angle."""
    angle = np.unwrap(np.arctan2(y / 0.25, x / 0.35))
    return abs(angle[-1] - angle[0]) / math.tau


def headless(script: str, duration: float) -> tuple[np.ndarray, object]:
    """The ground truth (steps, 3) of `script` run headless on the track, and the run's tally."""
    poses: list[np.ndarray] = []
    _, tally = run(Trial(Script(str(EXAMPLES / script)), world=str(TRACK), duration=duration),
                   each_step=lambda sim: poses.append(sim.true_pose[0].copy()))
    return np.array(poses), tally


def test_the_line_demo_goes_round_the_track_headless():
    poses, tally = headless('line_demo.py', LAP)
    away = off_line(poses[:, 0], poses[:, 1])
    print(f'line_demo: {laps(poses[:, 0], poses[:, 1]):.2f} laps in {LAP} s, at most {away.max() * 1000:.1f} mm '
          f'off the line')
    assert laps(poses[:, 0], poses[:, 1]) > 1.0 and away.max() < NEAR_LINE
    assert tally.figures[0].world_contacts == 0


def test_line_follower_with_webots_thresholds_follows_the_track_headless():
    poses, _ = headless('line_follower.py', 30.0)
    assert laps(poses[:, 0], poses[:, 1]) > 0.5 and off_line(poses[:, 0], poses[:, 1]).max() < NEAR_LINE


def test_the_line_demo_follows_the_track_over_ros(launch, tmp_path):
    """Through `bringup --controller` (sim, webots_controller and recorder as processes, lockstep, as fast as
    possible): half a lap, never farther from the line than headless allows."""
    from epuck_ros.bag.reader import Bag
    from epuck_ros.bag.run_summary import load_runs
    duration = 40.0
    bringup = launch('bringup', '--controller', str(EXAMPLES / 'line_demo.py'), '--world', str(TRACK),
                     '--duration', str(duration), '--real-time-factor', '0', '--record', str(tmp_path / 'run'))
    assert bringup.proc.wait(timeout=300) == 0, bringup.output()
    with Bag(tmp_path / 'run') as bag:
        [recorded] = load_runs(bag)
    truth = recorded.truth
    away = off_line(truth.x, truth.y)
    print(f'line_demo over ROS: {laps(truth.x, truth.y):.2f} laps in {duration} s, at most {away.max() * 1000:.1f} '
          f'mm off the line')
    assert truth.t[-1] - truth.t[0] == pytest.approx(duration, abs=0.1)
    assert laps(truth.x, truth.y) > 0.45 and away.max() < NEAR_LINE
    assert processes_in_this_domain() == []
