"""What a course user (or teacher) wants to know about a recorded e-puck run, for one robot or many.

Duration, distance travelled, mean speed, the closest approach the IR sensors saw, contacts with walls
and obstacles and with other robots, and what kind of run it was (standing, a straight line, a spin in
place, a circle, a rectangle, free motion such as `avoid`) with that shape's figures only: the heading rate
of a spin, the fitted circle of a circle, the corners of a rectangle. Reads only the topics it needs, with
the fast CDR paths, in one pass whatever the number of robots; no ROS needed.

`RunTally` is the one place distance and contacts are computed: `bag summary` feeds it the ground truth
read from a bag, `bringup` the ground truth it receives during a run, so the two always agree.
"""
from __future__ import annotations

import gc
import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field

import numpy as np

from epuck_ros.bag.cdr import CdrDecoder, odometry_fields, range_fields
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.model import RobotModel
from epuck_ros.world import World, world_from_yaml

ODOMETRY = 'nav_msgs/msg/Odometry'
RANGE = 'sensor_msgs/msg/Range'
STRING = 'std_msgs/msg/String'
TRAJECTORY_TOPICS = ('ground_truth', 'odom')
"""Basenames of the trajectory topics, the preferred one first (the true pose over the odometry)."""

CONTACT_MARGIN = 0.001
"""m; a body closer than this to a wall, an obstacle or another body counts as touching it."""
STRAIGHT_YAW_RATE = 0.05
"""rad/s; slower heading changes than this while moving count as driving straight."""
MOVING_SPEED = 0.005
"""m/s; slower than this the robot is standing (or turning in place)."""
MIN_SEGMENT_TIME = 0.3
"""s; straight stretches shorter than this are not sides of a shape."""
MIN_CORNER_DEG = 15.0
"""Straight stretches whose headings differ by less than this are one side; smaller turns are no corner."""
SLIP_RATIO = 0.5
"""Without a world: the true pose moving less than this fraction of the odometry's step means blocked."""
STILL_DISTANCE = 0.01
"""m; a run travelling less than this (a quarter of the body radius) stayed in place."""
CORNER_RANGE_DEG = (45.0, 135.0)
"""A rectangle's corners, as driven: the course's timed turns make 82.4-85.0° ones (31 or 32 steps), not 90°."""
MIN_SIDE_RATIO = 0.25
"""A rectangle's shortest side is at least this fraction of its longest (else it is free motion)."""
CIRCLE_RMS_RATIO = 0.1
"""A circle's points lie within this fraction of its radius (rms) of the fitted circle."""


@dataclass
class Trajectory:
    """A pose topic sorted by time: stamps (s since the run's start), positions, heading, twist."""

    topic: str
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray
    stamps_ns: np.ndarray

    @property
    def distance(self) -> float:
        return float(np.hypot(np.diff(self.x), np.diff(self.y)).sum())

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0]) if len(self.t) else 0.0

    def from_pose(self, x0: float, y0: float, yaw0: float) -> Trajectory:
        """This trajectory, given in a frame whose origin is the pose (x0, y0, yaw0), in the outer frame.

        Odometry starts at (0, 0, 0) at the robot's start pose: `odom.from_pose(*start)` is it in the world.
        """
        cos, sin = math.cos(yaw0), math.sin(yaw0)
        return Trajectory(self.topic, self.t, x0 + cos * self.x - sin * self.y, y0 + sin * self.x + cos * self.y,
                          yaw0 + self.yaw, self.stamps_ns)


@dataclass
class RunData:
    """Everything a summary or plot needs from one robot's topics."""

    bag_path: str
    namespace: str
    trajectory: Trajectory
    truth: Trajectory | None
    odom: Trajectory | None
    ranges: tuple[np.ndarray, np.ndarray, tuple[bytes, ...]] | None
    """(stamps s, ranges m, frame_ids) of the proximity topic."""
    world: World | None
    closed_properly: bool
    start_pose: tuple[float, float, float] | None = None
    """The robot's start pose in the world (where its odometry frame is), when the bag says."""
    world_problem: str | None = None
    """Why the bag's world topic could not be used, if it could not."""

    @property
    def name(self) -> str:
        """The robot's name: the last part of its namespace ('' for a one-robot bag's '/')."""
        return self.namespace.rstrip('/').rsplit('/', 1)[-1]

    def path_in_world(self) -> Trajectory:
        """The true path, else the odometry in the world (else in its own frame, when nothing places it)."""
        if self.truth is not None:
            return self.truth
        return self.odom_in_world() or self.trajectory

    def odom_in_world(self) -> Trajectory | None:
        """The odometry drawn from the robot's start pose (or, without one, from where the truth began)."""
        if self.odom is None:
            return None
        if self.start_pose is not None:
            return self.odom.from_pose(*self.start_pose)
        if self.truth is not None:
            common, in_truth, in_odom = np.intersect1d(self.truth.stamps_ns, self.odom.stamps_ns,
                                                       return_indices=True)
            if len(common):
                i, j = in_truth[0], in_odom[0]
                yaw0 = float(self.truth.yaw[i] - self.odom.yaw[j])
                cos, sin = math.cos(yaw0), math.sin(yaw0)
                x0 = float(self.truth.x[i] - (cos * self.odom.x[j] - sin * self.odom.y[j]))
                y0 = float(self.truth.y[i] - (sin * self.odom.x[j] + cos * self.odom.y[j]))
                return self.odom.from_pose(x0, y0, yaw0)
        return None


# -- distance and contacts: one source of truth for bag summary and bringup ---------------------------------

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

    @property
    def duration(self) -> float:
        return 0.0 if self.first_ns is None else (self.last_ns - self.first_ns) * 1e-9


class RunTally:
    """Distance travelled and contacts of each robot, from ground-truth samples (stamp, x, y) fed in time order.

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

    def add(self, name: str, stamp_ns: int, x: float, y: float) -> None:
        """One ground-truth sample of robot `name`."""
        i = self._index[name]
        figures, last = self.figures[i], self._last[i]
        if last is not None:
            figures.distance += math.hypot(x - last[0], y - last[1])
        self._last[i] = (x, y)
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

    def add_trajectory(self, name: str, stamps_ns: np.ndarray, x: np.ndarray, y: np.ndarray) -> None:
        """A run of samples of one robot (for several robots, interleave them by stamp with `add`)."""
        for stamp, px, py in zip(stamps_ns.tolist(), x.tolist(), y.tolist()):
            self.add(name, stamp, px, py)

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


def format_figures(figures: Sequence[RobotFigures], with_robots: bool | None = None) -> str:
    """One line per robot, as `bringup` prints its end-of-run summary."""
    with_robots = len(figures) > 1 if with_robots is None else with_robots
    lines = []
    for f in figures:
        robots = f', {f.robot_contacts} with robots' if with_robots else ''
        label = f'{f.name}: ' if f.name else ''
        lines.append(f'{label}{f.distance:.3f} m in {f.duration:.2f} s, '
                     f'{f.world_contacts} contacts with walls/obstacles{robots}')
    return '\n'.join(lines)


# -- reading a bag ------------------------------------------------------------------------------------------

def robot_namespaces(bag: Bag) -> list[str]:
    """Namespaces holding an ``odom`` or ``ground_truth`` Odometry topic: one per recorded robot."""
    found = {t.name.rsplit('/', 1)[0] or '/' for t in bag.topics_of_type(ODOMETRY)
             if t.name.rsplit('/', 1)[-1] in TRAJECTORY_TOPICS}
    return sorted(found, key=_natural_key)


def _natural_key(name: str) -> tuple:
    """epuck2 before epuck10."""
    stem = name.rstrip('0123456789')
    return (stem, int(name[len(stem):]) if len(stem) < len(name) else -1)


def _join(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


def load_run(bag: Bag, namespace: str | None = None) -> RunData:
    """One robot's run (the first robot's by default)."""
    return load_runs(bag, None if namespace is None else [namespace])[0]


def load_runs(bag: Bag, namespaces: Sequence[str] | None = None) -> list[RunData]:
    """Each robot's trajectories, proximity ranges, the world and start poses, in a single pass over the bag."""
    found = robot_namespaces(bag)
    if not found:
        raise BagError(f'{bag.path}: no odometry: the bag has no {ODOMETRY} topic named '
                       f'{" or ".join(TRAJECTORY_TOPICS)}')
    for namespace in namespaces or ():
        if namespace not in found:
            raise BagError(f'{bag.path}: no odometry under namespace {namespace} (robots: {", ".join(found)})')
    namespaces = list(namespaces or found)
    odometry = {ns: {name: _join(ns, name) for name in TRAJECTORY_TOPICS
                     if _join(ns, name) in bag.topics and bag.topics[_join(ns, name)].type_name == ODOMETRY}
                for ns in namespaces}
    proximity = {ns: _join(ns, 'proximity') for ns in namespaces
                 if _join(ns, 'proximity') in bag.topics and bag.topics[_join(ns, 'proximity')].type_name == RANGE}
    world_topic = _find_world_topic(bag, namespaces[0])

    rows: dict[str, list] = {}
    handlers = {}
    for topics in odometry.values():
        for topic in topics.values():
            rows[topic] = []
            handlers[topic] = (odometry_fields, rows[topic].append)
    for topic in proximity.values():
        rows[topic] = []
        handlers[topic] = (range_fields, rows[topic].append)
    world_messages: list[bytes] = []
    with _cyclic_gc_paused():
        for topic, _, _, buffer, start, end in bag.iter_raw([*handlers, *([world_topic] if world_topic else [])]):
            handler = handlers.get(topic)
            if handler is None:
                world_messages.append(bytes(buffer[start:end]))
            else:
                decode, append = handler
                append(decode(buffer, start))

    recorded = {ns: {name: topic for name, topic in topics.items() if rows[topic]} for ns, topics in odometry.items()}
    for ns, topics in recorded.items():
        if not topics:
            raise BagError(f'{bag.path}: no odometry: the odometry topics of {ns} have no messages')
    origin = min(row[0] for topics in recorded.values() for topic in topics.values() for row in rows[topic])
    world, world_problem = _world(bag, world_topic, world_messages[-1]) if world_messages else (None, None)
    runs = []
    for ns in namespaces:
        trajectories = {name: _trajectory(topic, rows[topic], origin) for name, topic in recorded[ns].items()}
        ranges = None
        if rows.get(proximity.get(ns, '')):
            stamps, values, frames = zip(*rows[proximity[ns]])
            ranges = ((np.array(stamps, dtype=np.int64) - origin) * 1e-9, np.array(values), frames)
        truth, odom = trajectories.get('ground_truth'), trajectories.get('odom')
        run = RunData(str(bag.path), ns, truth or odom, truth, odom, ranges, world, bag.closed_properly,
                      world_problem=world_problem)
        run.start_pose = start_pose(world, run.name, len(namespaces)) if world is not None else None
        runs.append(run)
    return runs


def start_pose(world: World, name: str, robots: int) -> tuple[float, float, float] | None:
    """Where robot `name` started in `world` (a one-robot bag's robot: the world's only one); None if not said."""
    for robot in world.robots:
        if robot.name == name:
            return robot.pose
    return world.robots[0].pose if robots == 1 and len(world.robots) == 1 else None


@contextmanager
def _cyclic_gc_paused() -> Iterator[None]:
    """Decoding keeps up to millions of small tuples alive; none is in a cycle, so the cyclic
    garbage collector would only rescan them over and over (a third of the time on a big bag)."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def _find_world_topic(bag: Bag, namespace: str) -> str | None:
    own = _join(namespace, 'world')
    if own in bag.topics and bag.topics[own].type_name == STRING:
        return own
    others = [t.name for t in bag.topics_of_type(STRING) if t.name.rsplit('/', 1)[-1] == 'world']
    return min(others, key=len) if others else None


def _world(bag: Bag, topic: str, message: bytes) -> tuple[World | None, str | None]:
    """The world the sim published as YAML, or None and why it cannot be used (collisions then come from slip)."""
    schema = bag.topics[topic]
    try:
        text = CdrDecoder(schema.type_name, schema.schema_text).decode(message)['data']
        return world_from_yaml(text, source=f'{bag.path} topic {topic}'), None
    except (ValueError, KeyError) as error:
        return None, f'world not used: {" ".join(str(error).split())[:200]}'


def _trajectory(topic: str, rows: list[tuple], origin_ns: int) -> Trajectory:
    """Odometry rows (stamp ns, x, y, yaw, v, w) sorted by stamp; t counted from `origin_ns`."""
    stamps, x, y, yaw, _, _ = (np.array(column) for column in zip(*rows))
    stamps = stamps.astype(np.int64)
    order = np.argsort(stamps, kind='stable')
    stamps = stamps[order]
    return Trajectory(topic, (stamps - origin_ns) * 1e-9, x[order], y[order], np.unwrap(yaw[order]), stamps)


# -- what kind of run it was ----------------------------------------------------------------------------------

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


def classify(trajectory: Trajectory) -> Motion:
    """Say what the run was, from the path and heading alone; a shape's figures only when it is that shape."""
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
    corners = _rectangle_corners(trajectory, _sides(trajectory, segments))
    if corners is not None and straight_time >= 0.5 * moving_time:
        return Motion('rectangle', corners=corners)
    return Motion('free motion')


def _straight_line(trajectory: Trajectory) -> StraightLine:
    dx, dy = trajectory.x[-1] - trajectory.x[0], trajectory.y[-1] - trajectory.y[0]
    length = math.hypot(dx, dy)
    heading = math.atan2(dy, dx) if length > 0.0 else float(trajectory.yaw[0])
    across = np.abs(-(trajectory.x - trajectory.x[0]) * math.sin(heading)
                    + (trajectory.y - trajectory.y[0]) * math.cos(heading))
    return StraightLine(length, math.degrees(heading), float(across.max()))


def _rectangle_corners(trajectory: Trajectory, sides: list[tuple[float, float, int]]) -> Corners | None:
    """The corners when the sides make a rectangle as driven: at least 3 sides of comparable length (the last
    may be cut short), and turns of 45-135° all one way; a turn after the last side (closing the rectangle)
    is a corner too."""
    if len(sides) < 3:
        return None
    headings = [heading for heading, _, _ in sides]
    angles = [math.degrees(b - a) for a, b in zip(headings, headings[1:])]
    trailing = math.degrees(float(trajectory.yaw[-1]) - headings[-1])
    if abs(trailing) >= CORNER_RANGE_DEG[0]:
        angles.append(trailing)
    lengths = [length for _, length, _ in sides]
    low, high = CORNER_RANGE_DEG
    if (not all(low <= abs(a) <= high for a in angles) or len({a > 0 for a in angles}) != 1
            or min(lengths[:-1]) < MIN_SIDE_RATIO * max(lengths)):  # the run may stop part-way along the last
        return None
    return Corners(angles, lengths)


# -- the summary --------------------------------------------------------------------------------------------

@dataclass
class RunSummary:
    bag: str
    namespace: str
    trajectory_topic: str
    motion: str
    duration: float
    distance: float
    mean_speed: float
    closest_approach: float | None
    closest_sensor: str | None
    closest_time: float | None
    collisions: int | None
    """Contacts with walls and obstacles."""
    collisions_from: str
    robot_collisions: int | None
    """Contacts with other robots (None in a one-robot bag)."""
    straight: StraightLine | None
    spin: Spin | None
    circle: CircleFit | None
    corners: Corners | None
    closed_properly: bool
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class BagSummary:
    """Every robot's summary, and what involves several of them."""

    bag: str
    robots: list[RunSummary]
    robot_robot_contacts: int | None
    """Contacts between two robots, each counted once (None in a one-robot bag)."""
    contacts: list[Contact]
    """Where each contact began, for the plot."""

    def to_dict(self) -> dict:
        if len(self.robots) == 1:
            return self.robots[0].to_dict()
        return {'bag': self.bag, 'robots': [r.to_dict() for r in self.robots],
                'robot_robot_contacts': self.robot_robot_contacts}


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
        tally.add_trajectory(with_truth[0].name, truth.stamps_ns, truth.x, truth.y)
    elif with_truth:
        names = np.concatenate([np.full(len(r.truth.t), i) for i, r in enumerate(with_truth)])
        stamps = np.concatenate([r.truth.stamps_ns for r in with_truth])
        xs = np.concatenate([r.truth.x for r in with_truth])
        ys = np.concatenate([r.truth.y for r in with_truth])
        labels = [run.name for run in with_truth]
        add = tally.add
        for i in np.argsort(stamps, kind='stable').tolist():
            add(labels[names[i]], int(stamps[i]), float(xs[i]), float(ys[i]))
    return tally


def summarise_runs(runs: Sequence[RunData], model: RobotModel = RobotModel()) -> BagSummary:
    """Summaries of every robot of a bag (robot-robot contacts need them all)."""
    tally = tally_runs(runs, model)
    figures = {f.name: f for f in tally.figures}
    several = len(runs) > 1
    summaries = []
    for run in runs:
        trajectory = run.trajectory
        notes = [] if run.closed_properly else ['bag not closed properly: figures from its complete chunks']
        notes += [run.world_problem] if run.world_problem else []
        robot_collisions = None
        if run.world is not None and run.truth is not None:
            collisions, source = figures[run.name].world_contacts, 'world'
            robot_collisions = figures[run.name].robot_contacts if several else None
        elif run.truth is not None and run.odom is not None:
            collisions, source = contacts_from_slip(run.truth, run.odom), 'odom vs ground_truth'
        else:
            collisions, source = None, 'unknown'
            notes.append('collisions unknown: needs ground_truth and the world (or odom) topics')
        if several and run.truth is not None and robot_collisions is None:
            robot_collisions = figures[run.name].robot_contacts
        closest, sensor, when = None, None, None
        if run.ranges is not None:
            stamps, values, frames = run.ranges
            finite = np.flatnonzero(np.isfinite(values))
            if len(finite):
                best = finite[np.argmin(values[finite])]
                closest, sensor, when = float(values[best]), frames[best].decode(errors='replace'), float(stamps[best])
        motion = classify(trajectory)
        distance = figures[run.name].distance if run.truth is not None else trajectory.distance
        duration = trajectory.duration
        summaries.append(RunSummary(
            bag=run.bag_path, namespace=run.namespace, trajectory_topic=trajectory.topic, motion=motion.kind,
            duration=duration, distance=distance, mean_speed=distance / duration if duration > 0 else 0.0,
            closest_approach=closest, closest_sensor=sensor, closest_time=when,
            collisions=collisions, collisions_from=source, robot_collisions=robot_collisions,
            straight=motion.straight, spin=motion.spin, circle=motion.circle, corners=motion.corners,
            closed_properly=run.closed_properly, notes=notes))
    return BagSummary(runs[0].bag_path if runs else '', summaries,
                      tally.robot_robot_contacts if several else None, tally.contacts)


def summarise(run: RunData, model: RobotModel = RobotModel()) -> RunSummary:
    """One robot's summary (robot-robot contacts need `summarise_runs` over all robots)."""
    return summarise_runs([run], model).robots[0]


# -- text -----------------------------------------------------------------------------------------------------

def turn_direction(rate: float) -> str:
    return 'counter-clockwise' if rate > 0 else 'clockwise'


def shape_lines(summary: RunSummary | Motion) -> list[tuple[str, str]]:
    """The figures of the run's shape, as (label, text): of a bag's summary, or of a Motion (`bringup`)."""
    if summary.straight is not None:
        s = summary.straight
        return [('Straight line', f'{s.length:.4f} m heading {s.heading_deg:.1f}°, '
                                  f'max deviation {s.max_deviation:.4f} m')]
    if summary.spin is not None:
        s = summary.spin
        return [('Heading rate', f'{math.degrees(s.heading_rate):.1f}°/s ({s.heading_rate:.3f} rad/s, '
                                 f'{turn_direction(s.heading_rate)}), {s.turns:.2f} turns')]
    if summary.circle is not None:
        c = summary.circle
        return [('Circle fit', f'radius {c.radius:.4f} m, centre ({c.centre[0]:.3f}, {c.centre[1]:.3f}), '
                               f'rms {c.rms_error:.4f} m, {c.laps:.2f} laps')]
    if summary.corners is not None:
        angles = ', '.join(f'{a:.1f}°' for a in summary.corners.angles_deg)
        sides = ', '.join(f'{s:.3f}' for s in summary.corners.side_lengths)
        return [('Corners', f'{len(summary.corners.angles_deg)}: {angles} (sides {sides} m)')]
    return []


def _collisions_text(summary: RunSummary) -> str:
    if summary.collisions is None:
        return 'unknown'
    robots = '' if summary.robot_collisions is None else f', {summary.robot_collisions} with robots'
    return f'{summary.collisions} with walls/obstacles{robots} (from {summary.collisions_from})'


def format_summary(summary: RunSummary) -> str:
    """One robot's summary as aligned text lines, in the style of ``ros2 bag info``."""
    lines = [('Bag', summary.bag), ('Robot', summary.namespace),
             ('Trajectory', summary.trajectory_topic),
             ('Motion', summary.motion),
             ('Duration', f'{summary.duration:.3f} s'),
             ('Distance', f'{summary.distance:.4f} m'),
             ('Mean speed', f'{summary.mean_speed:.4f} m/s')]
    if summary.closest_approach is None:
        lines.append(('Closest approach', 'nothing seen within IR range'))
    else:
        lines.append(('Closest approach', f'{summary.closest_approach:.4f} m '
                                          f'({summary.closest_sensor} at t={summary.closest_time:.2f} s)'))
    lines.append(('Collisions', _collisions_text(summary)))
    lines += shape_lines(summary)
    lines += [('Note', note) for note in summary.notes]
    return _aligned(lines)


def _aligned(lines: list[tuple[str, str]]) -> str:
    return '\n'.join(f'{label + ":":<19}{value}' for label, value in lines)


def format_bag_summary(summary: BagSummary) -> str:
    """One robot: its summary. Several: the bag's totals, then one table row per robot."""
    if len(summary.robots) == 1:
        return format_summary(summary.robots[0])
    robots = summary.robots
    world = [r.collisions for r in robots if r.collisions is not None]
    head = [('Bag', summary.bag), ('Robots', str(len(robots))),
            ('Duration', f'{max(r.duration for r in robots):.3f} s'),
            ('Distance', f'{sum(r.distance for r in robots):.4f} m in total'),
            ('Collisions', f'{sum(world)} with walls/obstacles (from {robots[0].collisions_from}), '
                           f'{summary.robot_robot_contacts} between robots (from ground_truth poses)')]
    notes = sorted({note for r in robots for note in r.notes})
    head += [('Note', note) for note in notes]
    header = ('robot', 'distance m', 'speed m/s', 'walls/obst.', 'robots', 'closest m', 'motion')
    rows = [(r.namespace, f'{r.distance:.4f}', f'{r.mean_speed:.4f}',
             '?' if r.collisions is None else str(r.collisions),
             '?' if r.robot_collisions is None else str(r.robot_collisions),
             '-' if r.closest_approach is None else f'{r.closest_approach:.4f}', r.motion) for r in robots]
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]
    table = ['  '.join(cell.ljust(w) if i in (0, 6) else cell.rjust(w)
                       for i, (cell, w) in enumerate(zip(row, widths))).rstrip() for row in [header, *rows]]
    return _aligned(head) + '\n\n' + '\n'.join(table)
