"""The figures `bringup` prints at the end of a run, by the same code as `bag summary`.

`bag.tally.RunTally` for distance and contacts, `bag.shapes.classify` and `bag.summary_text.shape_lines` for
the shape driven: from the bag when the run was recorded, else from the ground-truth samples `bringup`
received. One source of truth, and one format.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from epuck_ros.bag.reader import Bag
from epuck_ros.bag.runs import Trajectory, load_runs
from epuck_ros.bag.shapes import Motion, classify_recorded, classify_runs
from epuck_ros.bag.summary_text import format_figures, shape_lines
from epuck_ros.bag.tally import RobotFigures, tally_runs
from epuck_ros.world import World


def from_bag(path: Path) -> tuple[list[RobotFigures], dict[str, Motion]]:
    """Each recorded robot's figures and the shape it drove, as `bag summary` computes them."""
    with Bag(path) as bag:
        runs = load_runs(bag)
    return tally_runs(runs).figures, {run.name: motion for run, motion in zip(runs, classify_recorded(runs))}


def motions_of(tracks: Mapping[str, Sequence[tuple[int, float, float, float]]], world: World | None
               ) -> dict[str, Motion]:
    """The shape each robot drove, from its ground-truth samples (stamp ns, x, y, yaw) in any order, repeats allowed,
    in `world` with the others."""
    return classify_runs({label: _trajectory(samples) for label, samples in tracks.items()}, world)


def _trajectory(samples: Sequence[tuple[int, float, float, float]]) -> Trajectory:
    rows = np.array(sorted(set(samples)), dtype=float).reshape(-1, 4)
    return trajectory_of_track(rows[:, 0].astype(np.int64), rows[:, 1], rows[:, 2], rows[:, 3])


def trajectory_of_track(stamps: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray) -> Trajectory:
    """The path driven, from ground-truth samples in time order without repeats (stamps in ns, as integers)."""
    t = (stamps - stamps[0]) * 1e-9 if len(stamps) else stamps.astype(float)
    return Trajectory('ground_truth', t, x, y, np.unwrap(yaw), stamps)


def lines(figures: list[RobotFigures], motions: Mapping[str, Motion]) -> list[str]:
    """One line per robot, then the figures of its shape (corners, circle fit, ...) as `bag summary` prints them."""
    result = []
    for figure, line in zip(figures, format_figures(figures).splitlines()):
        result.append(line)
        motion = motions.get(figure.name)
        result += [f'  {label}: {text}' for label, text in (shape_lines(motion) if motion is not None else [])]
    return result
