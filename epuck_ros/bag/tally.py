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
_NONE = -1
"""A stamp not yet seen (stamps are never negative)."""


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
    lasts. Feed samples as they come (`add` one at a time, in each robot's time order, or `add_step` every robot's
    of one stamp at once); a stamp some robot never reports is skipped for robot-robot contacts.

    Each robot's running figures are NumPy arrays over the robots (`figures` reads them out): a swarm's step is
    then a few array operations (`add_step`) instead of a Python call per robot, a third of bringup's CPU at
    1,000 robots. Both ways give the same numbers to the bit (a distance is a sum of `math.hypot`s in time order).
    """

    def __init__(self, names: Sequence[str], world: World | None = None,
                 body_radius: float = RobotModel().body_radius) -> None:
        self.names = list(names)
        self._index = {name: i for i, name in enumerate(names)}
        self.world = world
        self.body_radius = body_radius
        self.contacts: list[Contact] = []
        count = len(names)
        self._distance = np.zeros(count)
        self._samples = np.zeros(count, dtype=np.int64)
        self._first_ns = np.full(count, _NONE, dtype=np.int64)
        self._last_ns = np.full(count, _NONE, dtype=np.int64)
        self._last = np.full((count, 3), np.nan)
        """(x, y, yaw) of each robot's last sample."""
        self._contacts = np.zeros((count, 2), dtype=np.int64)
        """Per robot, contacts with the world and with other robots."""
        self._touching = np.zeros(count, dtype=bool)
        self._pending: dict[int, dict[int, tuple[float, float]]] = {}
        """stamp -> {robot index: (x, y)} until every robot has reported that stamp."""
        self._pairs: set[tuple[int, int]] = set()
        """Robot pairs in contact at the last complete stamp."""

    @property
    def figures(self) -> list[RobotFigures]:
        """Each robot's figures so far, in the order of its names."""
        return [RobotFigures(name, distance, samples, None if first < 0 else first, None if last < 0 else last,
                             world, robots, None if samples == 0 else tuple(pose))
                for name, distance, samples, first, last, (world, robots), pose in zip(
                    self.names, self._distance.tolist(), self._samples.tolist(), self._first_ns.tolist(),
                    self._last_ns.tolist(), self._contacts.tolist(), self._last.tolist())]

    def add(self, name: str, stamp_ns: int, x: float, y: float, yaw: float) -> None:
        """One ground-truth sample of robot `name`."""
        i = self._index[name]
        if self._samples[i]:
            last_x, last_y, _ = self._last[i].tolist()
            self._distance[i] += math.hypot(x - last_x, y - last_y)
        else:
            self._first_ns[i] = stamp_ns
        self._last[i] = x, y, yaw
        self._samples[i] += 1
        self._last_ns[i] = stamp_ns
        if self.world is not None:
            touching = self.world.anything_within(x, y, self.body_radius + CONTACT_MARGIN)
            if touching and not self._touching[i]:
                self._contacts[i, 0] += 1
                self.contacts.append(Contact(name, stamp_ns, x, y, 'world'))
            self._touching[i] = touching
        if len(self.names) > 1:
            self._pend(i, stamp_ns, x, y)

    def add_step(self, stamp_ns: int, x: np.ndarray, y: np.ndarray, yaw: np.ndarray) -> None:
        """Every robot's sample of one stamp (x, y, yaw: (N,) in the order of the names): what `add` does for each
        robot in turn, in NumPy over the robots."""
        had = self._samples > 0
        if had.any():
            last_x, last_y = self._last[had, 0].tolist(), self._last[had, 1].tolist()
            hypot = math.hypot   # `add`'s very function: the same bits
            self._distance[had] += [hypot(nx - lx, ny - ly)
                                    for nx, ny, lx, ly in zip(x[had].tolist(), y[had].tolist(), last_x, last_y)]
        self._first_ns[~had] = stamp_ns
        self._last[:, 0], self._last[:, 1], self._last[:, 2] = x, y, yaw
        self._samples += 1
        self._last_ns[:] = stamp_ns
        xy = np.column_stack((x, y))
        if self.world is not None:
            touching = self.world.anything_within_each(xy, self.body_radius + CONTACT_MARGIN)
            for i in np.flatnonzero(touching & ~self._touching).tolist():
                self._contacts[i, 0] += 1
                self.contacts.append(Contact(self.names[i], stamp_ns, *xy[i].tolist(), 'world'))
            self._touching = touching
        if len(self.names) > 1:
            for stamp in [stamp for stamp in self._pending if stamp <= stamp_ns]:   # older: lost a sample
                del self._pending[stamp]
            self._robot_step(stamp_ns, xy)

    def add_trajectory(self, name: str, stamps_ns: np.ndarray, x: np.ndarray, y: np.ndarray, yaw: np.ndarray
                       ) -> None:
        """A run of samples of one robot (for several robots, interleave them by stamp with `add` or `add_step`)."""
        for stamp, px, py, pyaw in zip(stamps_ns.tolist(), x.tolist(), y.tolist(), yaw.tolist()):
            self.add(name, stamp, px, py, pyaw)

    def _pend(self, i: int, stamp_ns: int, x: float, y: float) -> None:
        poses = self._pending.setdefault(stamp_ns, {})
        poses[i] = (x, y)
        if len(poses) < len(self.names):
            return
        for stamp in list(self._pending):  # oldest first; older incomplete stamps lost a sample: skip them
            del self._pending[stamp]
            if stamp == stamp_ns:
                break
        self._robot_step(stamp_ns, np.array([poses[i] for i in range(len(self.names))]))

    def _robot_step(self, stamp_ns: int, xy: np.ndarray) -> None:
        """Pairs in contact at one stamp, every robot's (x, y) in `xy` (sweep along x: only neighbours in x are
        compared), new ones counted."""
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
                self._contacts[me, 1] += 1
                self.contacts.append(Contact(self.names[me], stamp_ns, *xy[me].tolist(), 'robot', self.names[other]))
        self._pairs = pairs

    @property
    def robot_robot_contacts(self) -> int:
        """Contacts between two robots, each counted once (not once per robot)."""
        return int(self._contacts[:, 1].sum()) // 2


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
    """Feed every robot's ground truth to one RunTally, interleaved by stamp as the sim published it: every robot's
    sample of a stamp at once where each has one (`add_step`)."""
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
        order = np.argsort(stamps, kind='stable')
        bounds = np.flatnonzero(np.diff(stamps[order])) + 1
        for group in np.split(order, bounds):   # a stamp's samples, by robot (the sort is stable)
            if len(group) == len(labels) and np.array_equal(names[group], np.arange(len(labels))):
                tally.add_step(int(stamps[group[0]]), xs[group], ys[group], yaws[group])
                continue
            for i in group.tolist():   # a stamp some robot lacks (or repeats)
                tally.add(labels[names[i]], int(stamps[i]), float(xs[i]), float(ys[i]), float(yaws[i]))
    return tally
