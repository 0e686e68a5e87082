"""What kind of run it was, from the path and heading: standing, a straight line, a spin in place, a circle, a
rectangle or free motion such as `avoid`, with that shape's figures only. Where the world is known, also from what
was around the robot where it turned: obstacle avoidance turns in place only where its sensors see something, a
rectangle's corners are turned in the open (`surroundings`)."""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from epuck_ros.bag.runs import RunData, Trajectory
from epuck_ros.model import RobotModel
from epuck_ros.world import World

STRAIGHT_YAW_RATE = 0.05
"""rad/s; slower heading changes than this while moving count as driving straight."""
MOVING_SPEED = 0.005
"""m/s; slower than this the robot is standing (or turning in place)."""
MIN_SEGMENT_TIME = 0.3
"""s; straight stretches shorter than this are not sides of a shape."""
MIN_CORNER_DEG = 15.0
"""Straight stretches whose headings differ by less than this are one side; smaller turns are no corner."""
STILL_DISTANCE = 0.01
"""m; a run travelling less than this (a quarter of the body radius) stayed in place."""
CORNER_RANGE_DEG = (45.0, 135.0)
"""A rectangle's corners, as driven: the course's timed turns make 82.4-85.0° ones (31 or 32 steps), not 90°."""
CORNER_SPREAD_DEG = 5.0
"""A rectangle's corners are alike: they differ by this at most (a timer or the odometry ends every turn alike).
Obstacle avoidance turns until the way is clear, by as much as the wall it met asks (`avoid_obstacles.py` in the
default arena: 110.7°, 87.7°, 70.0°, 58.9°)."""
MIN_SIDE_RATIO = 0.25
"""A rectangle's shortest side is at least this fraction of its longest (else it is free motion)."""
SIDE_TOLERANCE = 0.1
"""A rectangle's opposite sides are as long as each other to within this fraction of the longer one; its last side
(the run may end part-way along it) is at most that much longer than the side opposite. Obstacle avoidance drives
until the next wall, however far that is."""
CIRCLE_RMS_RATIO = 0.1
"""A circle's points lie within this fraction of its radius (rms) of the fitted circle."""
Clearance = Callable[[np.ndarray], np.ndarray]
"""Stamps (N,) in ns -> the distance (N,) from the robot's centre at each to the nearest wall, obstacle or other
robot's body (`surroundings`)."""


@dataclass
class StraightLine:
    length: float
    """m from the first to the last pose."""
    heading_deg: float
    max_deviation: float
    """m; the farthest the robot strayed from the line through its first and last poses."""


@dataclass
class Spin:
    heading_rate: float
    """rad/s while turning (the sign says which way: + is counter-clockwise)."""
    turns: float


@dataclass
class CircleFit:
    radius: float
    centre: tuple[float, float]
    rms_error: float
    laps: float


@dataclass
class Corners:
    angles_deg: list[float]
    """The heading change at each corner, as driven (+ is a left turn), including a turn after the last side."""
    side_lengths: list[float]


@dataclass
class Motion:
    """What a run was, and that shape's figures (the others None)."""

    kind: str
    straight: StraightLine | None = None
    spin: Spin | None = None
    circle: CircleFit | None = None
    corners: Corners | None = None


def fit_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, tuple[float, float], float]:
    """Least-squares circle (Kåsa): radius, centre and rms distance of the points from the circle."""
    design = np.column_stack([x, y, np.ones_like(x)])
    (a, b, c), *_ = np.linalg.lstsq(design, -(x * x + y * y), rcond=None)
    cx, cy = -a / 2.0, -b / 2.0
    radius = math.sqrt(max(cx * cx + cy * cy - c, 0.0))
    rms = float(np.sqrt(np.mean((np.hypot(x - cx, y - cy) - radius) ** 2)))
    return radius, (float(cx), float(cy)), rms


def _rates(trajectory: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per interval: duration (nan when not positive), speed, |heading rate|."""
    dt = np.diff(trajectory.t)
    dt[dt <= 0.0] = np.nan
    speed = np.hypot(np.diff(trajectory.x), np.diff(trajectory.y)) / dt
    return dt, speed, np.abs(np.diff(trajectory.yaw)) / dt


def straight_segments(trajectory: Trajectory) -> list[tuple[int, int]]:
    """Index ranges [i, j] where the robot moves with an almost constant heading for long enough."""
    _, speed, yaw_rate = _rates(trajectory)
    straight = (speed > MOVING_SPEED) & (yaw_rate < STRAIGHT_YAW_RATE)
    segments, start = [], None
    for i, flag in enumerate(np.append(straight, False)):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            if trajectory.t[i] - trajectory.t[start] >= MIN_SEGMENT_TIME:
                segments.append((start, i))
            start = None
    return segments


def _sides(trajectory: Trajectory, segments: list[tuple[int, int]]) -> list[tuple[float, float, int]]:
    """(heading, length, last index) of each side: straight segments on one heading (e.g. after backing off)
    are one side."""
    sides: list[tuple[float, float, int]] = []
    for i, j in segments:
        heading = float(np.mean(trajectory.yaw[i:j + 1]))
        length = float(np.hypot(trajectory.x[j] - trajectory.x[i], trajectory.y[j] - trajectory.y[i]))
        if sides and abs(heading - sides[-1][0]) < math.radians(MIN_CORNER_DEG):
            sides[-1] = (sides[-1][0], sides[-1][1] + length, j)
        else:
            sides.append((heading, length, j))
    return sides


def classify(trajectory: Trajectory, clearance: Clearance | None = None,
             model: RobotModel = RobotModel()) -> Motion:
    """Say what the run was, from the path and heading (and, given its `clearance`, where it turned); a shape's
    figures only when it is that shape."""
    if len(trajectory.t) < 3:
        return Motion('standing')
    dt, speed, yaw_rate = _rates(trajectory)
    turned = float(trajectory.yaw[-1] - trajectory.yaw[0])
    turning = yaw_rate >= STRAIGHT_YAW_RATE
    moving_time = float(np.nansum(np.where((speed > MOVING_SPEED) | turning, dt, 0.0)))
    if trajectory.distance < STILL_DISTANCE:
        turning_time = float(np.nansum(np.where(turning, dt, 0.0)))
        if abs(turned) < math.radians(MIN_CORNER_DEG) or turning_time <= 0.0:
            return Motion('standing')
        return Motion('spin in place', spin=Spin(turned / turning_time, abs(turned) / (2.0 * math.pi)))
    total_turn = float(np.abs(np.diff(trajectory.yaw)).sum())
    if total_turn < math.radians(MIN_CORNER_DEG):
        return Motion('straight line', straight=_straight_line(trajectory))
    segments = straight_segments(trajectory)
    straight_time = sum(trajectory.t[j] - trajectory.t[i] for i, j in segments)
    if abs(turned) >= math.pi and straight_time < 0.2 * moving_time:
        radius, centre, rms = fit_circle(trajectory.x, trajectory.y)
        if rms < CIRCLE_RMS_RATIO * radius:
            return Motion('circle', circle=CircleFit(radius, centre, rms, abs(turned) / (2.0 * math.pi)))
    sides = _sides(trajectory, segments)
    corners = _rectangle_corners(trajectory, sides)
    if corners is not None and straight_time >= 0.5 * moving_time and \
            _turned_in_the_open(trajectory, sides[:len(corners.angles_deg)], clearance, model):
        return Motion('rectangle', corners=corners)
    return Motion('free motion')


def classify_runs(paths: Mapping[str, Trajectory], world: World | None,
                  trajectories: Mapping[str, Trajectory] | None = None,
                  model: RobotModel = RobotModel()) -> dict[str, Motion]:
    """What each robot's run was: `paths` are the robots' paths in the world (what surrounded each is its world
    and the other robots), `trajectories` what to classify where it is not the path (odometry)."""
    motions = {}
    for name, path in paths.items():
        others = [other for key, other in paths.items() if key != name]
        classified = (trajectories or {}).get(name, path)
        motions[name] = classify(classified, surroundings(path, world, others, model), model)
    return motions


def classify_recorded(runs: Sequence[RunData], model: RobotModel = RobotModel()) -> list[Motion]:
    """What each robot of a bag did (`classify_runs` on their paths in the bag's world), in the order of `runs`."""
    world = next((run.world for run in runs if run.world is not None), None)
    motions = classify_runs({run.namespace: run.path_in_world() for run in runs}, world,
                            {run.namespace: run.trajectory for run in runs}, model)
    return [motions[run.namespace] for run in runs]


def surroundings(path: Trajectory, world: World | None, others: list[Trajectory],
                 model: RobotModel = RobotModel()) -> Clearance | None:
    """The clearance of the robot whose path in the world is `path`, at any of its stamps: from the walls and
    obstacles of `world` and the other robots' bodies, each where it was then (its nearest sample); None without
    a world."""
    if world is None or not len(path.t):
        return None

    def clearance(stamps: np.ndarray) -> np.ndarray:
        at = _nearest(path, stamps)
        xy = np.column_stack([path.x[at], path.y[at]])
        found = world.clearance(xy)
        for other in (other for other in others if len(other.t)):
            there = _nearest(other, stamps)
            found = np.minimum(found, np.hypot(other.x[there] - xy[:, 0], other.y[there] - xy[:, 1])
                               - model.body_radius)
        return found
    return clearance


def _nearest(trajectory: Trajectory, stamps: np.ndarray) -> np.ndarray:
    """The indexes of `trajectory`'s samples at (or just after) `stamps`."""
    return np.minimum(np.searchsorted(trajectory.stamps_ns, stamps), len(trajectory.stamps_ns) - 1)


def _turned_in_the_open(trajectory: Trajectory, sides: list[tuple[float, float, int]], clearance: Clearance | None,
                        model: RobotModel) -> bool:
    """Most corners (the ends of these sides) turned with nothing within the IR sensors' reach: obstacle avoidance
    turns in place only where a sensor sees something (within `ir_range` of the body), each time; a rectangle's
    corners lie in the open, and a timed one, whose turns of about 83° make it wander, now and then near a wall.
    True when nothing is known of the surroundings."""
    if clearance is None:
        return True
    ends = np.array([trajectory.stamps_ns[j] for _, _, j in sides])
    near = clearance(ends) < model.ir_range + model.body_radius
    return int(np.count_nonzero(~near)) > int(np.count_nonzero(near))


def _straight_line(trajectory: Trajectory) -> StraightLine:
    dx, dy = trajectory.x[-1] - trajectory.x[0], trajectory.y[-1] - trajectory.y[0]
    length = math.hypot(dx, dy)
    heading = math.atan2(dy, dx) if length > 0.0 else float(trajectory.yaw[0])
    across = np.abs(-(trajectory.x - trajectory.x[0]) * math.sin(heading)
                    + (trajectory.y - trajectory.y[0]) * math.cos(heading))
    return StraightLine(length, math.degrees(heading), float(across.max()))


def _rectangle_corners(trajectory: Trajectory, sides: list[tuple[float, float, int]]) -> Corners | None:
    """The corners when the sides make a rectangle as driven: at least 3 sides of comparable length (the last
    may be cut short), turns of 45-135° all one way and alike, opposite sides as long as each other; a turn after
    the last side (closing the rectangle, perhaps cut short too) is a corner as well."""
    if len(sides) < 3:
        return None
    headings = [heading for heading, _, _ in sides]
    turns = [math.degrees(b - a) for a, b in zip(headings, headings[1:])]
    trailing = math.degrees(float(trajectory.yaw[-1]) - headings[-1])
    angles = turns + ([trailing] if abs(trailing) >= CORNER_RANGE_DEG[0] else [])
    lengths = [length for _, length, _ in sides]
    low, high = CORNER_RANGE_DEG
    if (not all(low <= abs(a) <= high for a in angles) or len({a > 0 for a in angles}) != 1
            or min(lengths[:-1]) < MIN_SIDE_RATIO * max(lengths)):  # the run may stop part-way along the last
        return None
    if max(turns) - min(turns) > CORNER_SPREAD_DEG:
        return None
    opposite = zip(lengths, lengths[2:])
    *whole, (before_last, last) = opposite
    if any(abs(a - b) > SIDE_TOLERANCE * max(a, b) for a, b in whole) or \
            last > (1.0 + SIDE_TOLERANCE) * before_last:
        return None
    return Corners(angles, lengths)
