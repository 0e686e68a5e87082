"""What a course user (or teacher) wants to know about a recorded e-puck run.

Duration, distance travelled, mean speed, the closest approach the IR sensors saw, collisions,
and for the course shapes the figures a teacher checks: the radius of a fitted circle and the
corner angles of a rectangle. Reads only the topics it needs, with the fast CDR paths, so it
keeps up with any bag size; no ROS needed.
"""
from __future__ import annotations

import gc
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass, field

import numpy as np
import yaml

from epuck_ros.bag.cdr import CdrDecoder, odometry_fields, range_fields
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.model import RobotModel
from epuck_ros.world import World, world_from_dict

ODOMETRY = 'nav_msgs/msg/Odometry'
RANGE = 'sensor_msgs/msg/Range'
STRING = 'std_msgs/msg/String'
TRAJECTORY_TOPICS = ('ground_truth', 'odom')
"""Basenames of the trajectory topics, the preferred one first (the true pose over the odometry)."""

CONTACT_MARGIN = 0.001
"""m; the body closer than this to a wall or obstacle counts as touching it."""
STRAIGHT_YAW_RATE = 0.05
"""rad/s; slower heading changes than this while moving count as driving straight."""
MOVING_SPEED = 0.005
"""m/s; slower than this the robot is standing (or turning in place)."""
MIN_SEGMENT_TIME = 0.3
"""s; straight stretches shorter than this are not sides of a shape."""
MIN_CORNER_DEG = 15.0
"""Straight stretches whose headings differ by less than this are one side."""
SLIP_RATIO = 0.5
"""Without a world: the true pose moving less than this fraction of the odometry's step means blocked."""


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


@dataclass
class CircleFit:
    radius: float
    centre: tuple[float, float]
    rms_error: float
    laps: float


@dataclass
class Corners:
    angles_deg: list[float]
    side_lengths: list[float]


@dataclass
class RunSummary:
    bag: str
    namespace: str
    trajectory_topic: str
    duration: float
    distance: float
    mean_speed: float
    closest_approach: float | None
    closest_sensor: str | None
    closest_time: float | None
    collisions: int | None
    collisions_from: str
    circle: CircleFit | None
    corners: Corners | None
    closed_properly: bool
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)


def robot_namespaces(bag: Bag) -> list[str]:
    """Namespaces holding an ``odom`` or ``ground_truth`` Odometry topic: one per recorded robot."""
    found = {t.name.rsplit('/', 1)[0] or '/' for t in bag.topics_of_type(ODOMETRY)
             if t.name.rsplit('/', 1)[-1] in TRAJECTORY_TOPICS}
    return sorted(found)


def _join(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


def load_run(bag: Bag, namespace: str | None = None) -> RunData:
    """Read one robot's trajectories, proximity ranges and world from the bag in a single pass."""
    namespaces = robot_namespaces(bag)
    if not namespaces:
        raise BagError(f'{bag.path}: no odometry: the bag has no {ODOMETRY} topic named '
                       f'{" or ".join(TRAJECTORY_TOPICS)}')
    if namespace is None:
        namespace = namespaces[0]
    elif namespace not in namespaces:
        raise BagError(f'{bag.path}: no odometry under namespace {namespace} (robots: {", ".join(namespaces)})')
    odometry = {name: _join(namespace, name) for name in TRAJECTORY_TOPICS
                if _join(namespace, name) in bag.topics and bag.topics[_join(namespace, name)].type_name == ODOMETRY}
    proximity = _join(namespace, 'proximity')
    world_topic = _find_world_topic(bag, namespace)

    rows: dict[str, list] = {topic: [] for topic in odometry.values()}
    handlers = {topic: (odometry_fields, rows[topic].append) for topic in odometry.values()}
    if proximity in bag.topics and bag.topics[proximity].type_name == RANGE:
        rows[proximity] = []
        handlers[proximity] = (range_fields, rows[proximity].append)
    world_messages: list[bytes] = []
    with _cyclic_gc_paused():
        for topic, _, _, buffer, start, end in bag.iter_raw([*handlers, *([world_topic] if world_topic else [])]):
            handler = handlers.get(topic)
            if handler is None:
                world_messages.append(bytes(buffer[start:end]))
            else:
                decode, append = handler
                append(decode(buffer, start))

    recorded = {name: topic for name, topic in odometry.items() if rows[topic]}
    if not recorded:
        raise BagError(f'{bag.path}: no odometry: the odometry topics of {namespace} have no messages')
    origin = min(min(row[0] for row in rows[topic]) for topic in recorded.values())
    trajectories = {name: _trajectory(topic, rows[topic], origin) for name, topic in recorded.items()}
    ranges = None
    if rows.get(proximity):
        stamps, values, frames = zip(*rows[proximity])
        ranges = ((np.array(stamps, dtype=np.int64) - origin) * 1e-9, np.array(values), frames)
    world = _world(bag, world_topic, world_messages[-1]) if world_messages else None
    truth, odom = trajectories.get('ground_truth'), trajectories.get('odom')
    return RunData(str(bag.path), namespace, truth or odom, truth, odom, ranges, world, bag.closed_properly)


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
    return others[0] if others else None


def _world(bag: Bag, topic: str, message: bytes) -> World | None:
    """The world the sim published as YAML; None when it cannot be read (collisions then come from slip)."""
    schema = bag.topics[topic]
    try:
        text = CdrDecoder(schema.type_name, schema.schema_text).decode(message)['data']
        return world_from_dict(yaml.safe_load(text) or {}, source=f'{bag.path} topic {topic}')
    except (ValueError, yaml.YAMLError, KeyError):
        return None


def _trajectory(topic: str, rows: list[tuple], origin_ns: int) -> Trajectory:
    """Odometry rows (stamp ns, x, y, yaw, v, w) sorted by stamp; t counted from `origin_ns`."""
    stamps, x, y, yaw, _, _ = (np.array(column) for column in zip(*rows))
    stamps = stamps.astype(np.int64)
    order = np.argsort(stamps, kind='stable')
    stamps = stamps[order]
    return Trajectory(topic, (stamps - origin_ns) * 1e-9, x[order], y[order], np.unwrap(yaw[order]), stamps)


def fit_circle(x: np.ndarray, y: np.ndarray) -> tuple[float, tuple[float, float], float]:
    """Least-squares circle (Kåsa): radius, centre and rms distance of the points from the circle."""
    design = np.column_stack([x, y, np.ones_like(x)])
    (a, b, c), *_ = np.linalg.lstsq(design, -(x * x + y * y), rcond=None)
    cx, cy = -a / 2.0, -b / 2.0
    radius = math.sqrt(max(cx * cx + cy * cy - c, 0.0))
    rms = float(np.sqrt(np.mean((np.hypot(x - cx, y - cy) - radius) ** 2)))
    return radius, (float(cx), float(cy)), rms


def straight_segments(trajectory: Trajectory) -> list[tuple[int, int]]:
    """Index ranges [i, j] where the robot moves with an almost constant heading for long enough."""
    dt = np.diff(trajectory.t)
    dt[dt <= 0.0] = np.nan
    speed = np.hypot(np.diff(trajectory.x), np.diff(trajectory.y)) / dt
    yaw_rate = np.abs(np.diff(trajectory.yaw)) / dt
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


def _merge_collinear(trajectory: Trajectory, segments: list[tuple[int, int]]) -> list[tuple[float, float]]:
    """(heading, length) of each side: straight segments on one heading (e.g. after backing off) are one side."""
    sides: list[tuple[float, float]] = []
    for i, j in segments:
        heading = float(np.mean(trajectory.yaw[i:j + 1]))
        length = float(np.hypot(trajectory.x[j] - trajectory.x[i], trajectory.y[j] - trajectory.y[i]))
        if sides and abs(heading - sides[-1][0]) < math.radians(MIN_CORNER_DEG):
            sides[-1] = (sides[-1][0], sides[-1][1] + length)
        else:
            sides.append((heading, length))
    return sides


def course_shape(trajectory: Trajectory) -> tuple[CircleFit | None, Corners | None]:
    """Circle fit when the robot curves all along; corner angles when it drives straight sides."""
    if len(trajectory.t) < 3:
        return None, None
    segments = straight_segments(trajectory)
    turned = float(trajectory.yaw[-1] - trajectory.yaw[0])
    sides = _merge_collinear(trajectory, segments)
    if len(sides) >= 2:
        headings = [heading for heading, _ in sides]
        angles = [math.degrees(b - a) for a, b in zip(headings, headings[1:])]
        return None, Corners(angles, [length for _, length in sides])
    straight_time = sum(trajectory.t[j] - trajectory.t[i] for i, j in segments)
    if abs(turned) >= math.pi and straight_time < 0.2 * trajectory.duration:
        radius, centre, rms = fit_circle(trajectory.x, trajectory.y)
        return CircleFit(radius, centre, rms, abs(turned) / (2.0 * math.pi)), None
    return None, None


def contacts_with_world(trajectory: Trajectory, world: World, radius: float) -> int:
    """Times the body came within CONTACT_MARGIN of a wall or obstacle (each contact counted once)."""
    touching = world.clearance(np.column_stack([trajectory.x, trajectory.y])) < radius + CONTACT_MARGIN
    return int(touching[0]) + int(np.count_nonzero(touching[1:] & ~touching[:-1]))


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


def summarise(run: RunData, model: RobotModel = RobotModel()) -> RunSummary:
    trajectory = run.trajectory
    notes = [] if run.closed_properly else ['bag not closed properly: figures from its complete chunks']
    if run.world is not None and run.truth is not None:
        collisions, source = contacts_with_world(run.truth, run.world, model.body_radius), 'world'
    elif run.truth is not None and run.odom is not None:
        collisions, source = contacts_from_slip(run.truth, run.odom), 'odom vs ground_truth'
    else:
        collisions, source = None, 'unknown'
        notes.append('collisions unknown: needs ground_truth and the world (or odom) topics')
    closest, sensor, when = None, None, None
    if run.ranges is not None:
        stamps, values, frames = run.ranges
        finite = np.flatnonzero(np.isfinite(values))
        if len(finite):
            best = finite[np.argmin(values[finite])]
            closest, sensor, when = float(values[best]), frames[best].decode(errors='replace'), float(stamps[best])
    circle, corners = course_shape(trajectory)
    distance, duration = trajectory.distance, trajectory.duration
    return RunSummary(
        bag=run.bag_path, namespace=run.namespace, trajectory_topic=trajectory.topic,
        duration=duration, distance=distance, mean_speed=distance / duration if duration > 0 else 0.0,
        closest_approach=closest, closest_sensor=sensor, closest_time=when,
        collisions=collisions, collisions_from=source, circle=circle, corners=corners,
        closed_properly=run.closed_properly, notes=notes)


def format_summary(summary: RunSummary) -> str:
    """The summary as aligned text lines, in the style of ``ros2 bag info``."""
    lines = [('Bag', summary.bag), ('Robot', summary.namespace),
             ('Trajectory', summary.trajectory_topic),
             ('Duration', f'{summary.duration:.3f} s'),
             ('Distance', f'{summary.distance:.4f} m'),
             ('Mean speed', f'{summary.mean_speed:.4f} m/s')]
    if summary.closest_approach is None:
        lines.append(('Closest approach', 'nothing seen within IR range'))
    else:
        lines.append(('Closest approach', f'{summary.closest_approach:.4f} m '
                                          f'({summary.closest_sensor} at t={summary.closest_time:.2f} s)'))
    lines.append(('Collisions', 'unknown' if summary.collisions is None
                  else f'{summary.collisions} (from {summary.collisions_from})'))
    if summary.circle is not None:
        c = summary.circle
        lines.append(('Circle fit', f'radius {c.radius:.4f} m, centre ({c.centre[0]:.3f}, {c.centre[1]:.3f}), '
                                    f'rms {c.rms_error:.4f} m, {c.laps:.2f} laps'))
    if summary.corners is not None:
        angles = ', '.join(f'{a:.1f}°' for a in summary.corners.angles_deg)
        sides = ', '.join(f'{s:.3f}' for s in summary.corners.side_lengths)
        lines.append(('Corners', f'{angles} (sides {sides} m)'))
    lines += [('Note', note) for note in summary.notes]
    return '\n'.join(f'{label + ":":<19}{value}' for label, value in lines)
