"""Distance travelled, contacts and where each robot ended: the one place they are computed, for `bag summary` and
`bringup` alike.

`bag summary` feeds `RunTally` the ground truth read from a bag (`tally_runs`), `bringup` the ground truth it
receives during a run, so the two always agree.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from epuck_ros.bag.runs import RunData, Trajectory
from epuck_ros.bag.shapes import MOVING_SPEED
from epuck_ros.model import RobotModel
from epuck_ros.world import World

CONTACT_MARGIN = 0.001
"""m; a body closer than this to a wall, an obstacle or another body counts as touching it."""
SLIP_RATIO = 0.5
"""Without a world: the true pose moving less than this fraction of the odometry's step means blocked."""


@dataclass(frozen=True)
class Contact:
    """A contact's beginning: which robot, when (stamp ns), where, and against what."""

    robot: str
    stamp_ns: int
    x: float
    y: float
    kind: str
    """'world' (a wall or obstacle) or 'robot'."""
    other: str | None = None
    """The other robot, for a robot-robot contact."""


@dataclass
class RobotFigures:
    """One robot's figures from its ground truth: distance, time span and contacts (each counted once)."""

    name: str
    distance: float = 0.0
    samples: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    world_contacts: int = 0
    robot_contacts: int = 0
    last_pose: tuple[float, float, float] | None = None
    """(x, y, yaw) of the last sample, its yaw as fed (a bag's is unwrapped)."""

    @property
    def duration(self) -> float:
        return 0.0 if self.first_ns is None else (self.last_ns - self.first_ns) * 1e-9

    @property
    def final_pose(self) -> tuple[float, float, float] | None:
        """Where the robot ended: (x, y, yaw) of its last sample, the yaw in [-pi, pi] (as a sweep's CSV has it)."""
        if self.last_pose is None:
            return None
        x, y, yaw = self.last_pose
        return x, y, math.remainder(yaw, math.tau)


class RunTally:
    """Distance travelled, contacts and final pose of each robot, from ground-truth samples (stamp, x, y, yaw) fed in
    time order.

    A contact with a wall or obstacle begins when the body comes within CONTACT_MARGIN of it; one between
    two robots when their centres come within two body radii + CONTACT_MARGIN, judged on samples of the
    same stamp (every robot's truth is stamped with the step). Each contact counts once, however long it
    lasts. Feed samples as they come (`add` one at a time, in each robot's time order); a stamp some robot
    never reports is skipped for robot-robot contacts.
    """

    def __init__(self, names: Sequence[str], world: World | None = None,
                 body_radius: float = RobotModel().body_radius) -> None:
        self.figures = [RobotFigures(name) for name in names]
        self._index = {name: i for i, name in enumerate(names)}
        self.world = world
        self.body_radius = body_radius
        self.contacts: list[Contact] = []
        self._last: list[tuple[float, float] | None] = [None] * len(names)
        self._touching = [False] * len(names)
        self._pending: dict[int, dict[int, tuple[float, float]]] = {}
        """stamp -> {robot index: (x, y)} until every robot has reported that stamp."""
        self._pairs: set[tuple[int, int]] = set()
        """Robot pairs in contact at the last complete stamp."""

    def add(self, name: str, stamp_ns: int, x: float, y: float, yaw: float) -> None:
        """One ground-truth sample of robot `name`."""
        i = self._index[name]
        figures, last = self.figures[i], self._last[i]
        if last is not None:
            figures.distance += math.hypot(x - last[0], y - last[1])
        self._last[i] = (x, y)
        figures.last_pose = (x, y, yaw)
        figures.samples += 1
        figures.first_ns = stamp_ns if figures.first_ns is None else figures.first_ns
        figures.last_ns = stamp_ns
        if self.world is not None:
            touching = self.world.anything_within(x, y, self.body_radius + CONTACT_MARGIN)
            if touching and not self._touching[i]:
                figures.world_contacts += 1
                self.contacts.append(Contact(name, stamp_ns, x, y, 'world'))
            self._touching[i] = touching
        if len(self.figures) > 1:
            self._pend(i, stamp_ns, x, y)

    def add_trajectory(self, name: str, stamps_ns: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
                       ) -> None:
        """A run of samples of one robot (for several robots, interleave them by stamp with `add`)."""
        for stamp, px, py, pyaw in zip(stamps_ns.tolist(), x.tolist(), y.tolist(), yaw.tolist()):
            self.add(name, stamp, px, py, pyaw)

    def _pend(self, i: int, stamp_ns: int, x: float, y: float) -> None:
        poses = self._pending.setdefault(stamp_ns, {})
        poses[i] = (x, y)
        if len(poses) < len(self.figures):
            return
        for stamp in list(self._pending):  # oldest first; older incomplete stamps lost a sample: skip them
            del self._pending[stamp]
            if stamp == stamp_ns:
                break
        self._robot_step(stamp_ns, poses)

    def _robot_step(self, stamp_ns: int, poses: dict[int, tuple[float, float]]) -> None:
        """Pairs in contact at one stamp (sweep along x: only neighbours in x are compared), new ones counted."""
        xy = np.array([poses[i] for i in range(len(self.figures))])
        reach = 2.0 * self.body_radius + CONTACT_MARGIN
        order = np.argsort(xy[:, 0], kind='stable')
        sorted_xy = xy[order]
        pairs = set()
        for offset in range(1, len(order)):
            dx = sorted_xy[offset:, 0] - sorted_xy[:-offset, 0]
            near = dx < reach
            if not near.any():
                break
            dy = sorted_xy[offset:, 1] - sorted_xy[:-offset, 1]
            for k in np.flatnonzero(near & (np.hypot(dx, dy) < reach)).tolist():
                a, b = int(order[k]), int(order[k + offset])
                pairs.add((min(a, b), max(a, b)))
        for a, b in sorted(pairs - self._pairs):
            for me, other in ((a, b), (b, a)):
                self.figures[me].robot_contacts += 1
                name = self.figures[me].name
                self.contacts.append(Contact(name, stamp_ns, *poses[me], 'robot', self.figures[other].name))
        self._pairs = pairs

    @property
    def robot_robot_contacts(self) -> int:
        """Contacts between two robots, each counted once (not once per robot)."""
        return sum(f.robot_contacts for f in self.figures) // 2


def contacts_from_slip(truth: Trajectory, odom: Trajectory) -> int:
    """Without a world: steps where the wheels drove on but the true pose hardly moved, counted once per episode."""
    common, in_truth, in_odom = np.intersect1d(truth.stamps_ns, odom.stamps_ns, return_indices=True)
    if len(common) < 2:
        return 0
    true_step = np.hypot(np.diff(truth.x[in_truth]), np.diff(truth.y[in_truth]))
    odom_step = np.hypot(np.diff(odom.x[in_odom]), np.diff(odom.y[in_odom]))
    dt = np.diff(common) * 1e-9
    blocked = (odom_step > MOVING_SPEED * dt) & (true_step < SLIP_RATIO * odom_step)
    return int(blocked[0]) + int(np.count_nonzero(blocked[1:] & ~blocked[:-1]))


def tally_runs(runs: Sequence[RunData], model: RobotModel = RobotModel()) -> RunTally:
    """Feed every robot's ground truth to one RunTally, interleaved by stamp as the sim published it."""
    with_truth = [run for run in runs if run.truth is not None]
    world = runs[0].world if runs else None
    tally = RunTally([run.name for run in with_truth], world, model.body_radius)
    if len(with_truth) == 1:
        truth = with_truth[0].truth
        tally.add_trajectory(with_truth[0].name, truth.stamps_ns, truth.x, truth.y, truth.yaw)
    elif with_truth:
        names = np.concatenate([np.full(len(r.truth.t), i) for i, r in enumerate(with_truth)])
        stamps = np.concatenate([r.truth.stamps_ns for r in with_truth])
        xs = np.concatenate([r.truth.x for r in with_truth])
        ys = np.concatenate([r.truth.y for r in with_truth])
        yaws = np.concatenate([r.truth.yaw for r in with_truth])
        labels = [run.name for run in with_truth]
        add = tally.add
        for i in np.argsort(stamps, kind='stable').tolist():
            add(labels[names[i]], int(stamps[i]), float(xs[i]), float(ys[i]), float(yaws[i]))
    return tally
