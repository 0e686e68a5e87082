"""Runs read from a bag: each robot's trajectories, proximity ranges, the world and start poses, in one pass.

Reads only the topics it needs, with the fast CDR paths, whatever the number of robots; no ROS needed. What
is made of a run: the tally (`tally`), its shape (`shapes`), the summary (`run_summary`) and plot (`plot`).
"""
from __future__ import annotations

import gc
import math
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from epuck_ros.bag.cdr import CdrDecoder, odometry_fields, range_fields
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.conversions import nanoseconds_from_stamp, quaternion_from_yaw, yaw_from_quaternion
from epuck_ros.swarm_messages import OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmReader
from epuck_ros.world import World, world_from_yaml

ODOMETRY = 'nav_msgs/msg/Odometry'
RANGE = 'sensor_msgs/msg/Range'
STRING = 'std_msgs/msg/String'
FLOAT64_ARRAY = 'std_msgs/msg/Float64MultiArray'
TRAJECTORY_TOPICS = ('ground_truth', 'odom')
"""Basenames of the trajectory topics, the preferred one first (the true pose over the odometry)."""


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


def robot_namespaces(bag: Bag) -> list[str]:
    """Namespaces holding an ``odom`` or ``ground_truth`` Odometry topic: one per recorded robot; without any, the
    robots of the swarm observation (`<namespace><robot>` as their own topics would be named)."""
    found = _robot_topics_namespaces(bag)
    if found:
        return found
    swarm = _swarm_topic(bag)
    if swarm is None:
        return []
    prefix = swarm[:-len(OBSERVATION_TOPIC)]
    for _, _, _, buffer, start, end in bag.iter_raw([swarm]):
        read = SwarmReader().read(bytes(buffer[start:end]))
        if read is not None and read.fields == OBSERVATION_FIELDS:
            return [prefix + robot for robot in read.robots]
    return []


def _robot_topics_namespaces(bag: Bag) -> list[str]:
    found = {t.name.rsplit('/', 1)[0] or '/' for t in bag.topics_of_type(ODOMETRY)
             if t.name.rsplit('/', 1)[-1] in TRAJECTORY_TOPICS}
    return sorted(found, key=_natural_key)


def _swarm_topic(bag: Bag) -> str | None:
    """The swarm observation's topic (the shortest name, if several), or None."""
    names = [t.name for t in bag.topics_of_type(FLOAT64_ARRAY) if t.name.endswith('/' + OBSERVATION_TOPIC)]
    return min(names, key=len) if names else None


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
    """Each robot's trajectories, proximity ranges, the world and start poses, in a single pass over the bag. A
    swarm's bag (robots without their own odometry topics: the simulator made them only for whoever read them) is
    read from its swarm observation (`_load_swarm_runs`)."""
    if not _robot_topics_namespaces(bag) and _swarm_topic(bag) is not None:
        return _load_swarm_runs(bag, _swarm_topic(bag), namespaces)
    namespaces = _checked_namespaces(bag, namespaces)
    odometry = {ns: {name: _join(ns, name) for name in TRAJECTORY_TOPICS
                     if _join(ns, name) in bag.topics and bag.topics[_join(ns, name)].type_name == ODOMETRY}
                for ns in namespaces}
    proximity = {ns: _join(ns, 'proximity') for ns in namespaces
                 if _join(ns, 'proximity') in bag.topics and bag.topics[_join(ns, 'proximity')].type_name == RANGE}
    world_topic = _find_world_topic(bag, namespaces[0])
    rows, world_messages = _read_rows(bag, [topic for topics in odometry.values() for topic in topics.values()],
                                      list(proximity.values()), world_topic)
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


def _load_swarm_runs(bag: Bag, topic: str, namespaces: Sequence[str] | None) -> list[RunData]:
    """Each robot's ground truth and odometry from the swarm observation `topic` (`swarm_messages`): one message per
    step for all robots, read into one (steps, robots, fields) array; a yaw as a ground_truth or odom message would
    carry it (through its quaternion), so the figures are those of the robots' own topics."""
    prefix = topic[:-len(OBSERVATION_TOPIC)]
    world_topic = _find_world_topic(bag, prefix)
    reader, robots = SwarmReader(), None
    stamps, steps, world_messages = [], [], []
    with _cyclic_gc_paused():
        for name, _, _, buffer, start, end in bag.iter_raw([topic, *([world_topic] if world_topic else [])]):
            if name != topic:
                world_messages.append(bytes(buffer[start:end]))
                continue
            read = reader.read(bytes(buffer[start:end]))
            if read is None or read.stamp is None or read.fields != OBSERVATION_FIELDS:
                continue
            robots = read.robots if robots is None else robots
            if read.robots == robots:   # one simulator's robots
                stamps.append(nanoseconds_from_stamp(*read.stamp))
                steps.append(read.data)
    if not steps:
        raise BagError(f'{bag.path}: no odometry: {topic} has no step of the swarm observation')
    found = [prefix + robot for robot in robots]
    for namespace in namespaces or ():
        if namespace not in found:
            raise BagError(f'{bag.path}: no odometry under namespace {namespace} (robots: {", ".join(found)})')
    order = np.argsort(stamps, kind='stable')
    stamps_ns = np.array(stamps, dtype=np.int64)[order]
    keep = np.concatenate(([True], np.diff(stamps_ns) != 0))   # a step sent again (see `_trajectory`)
    stamps_ns, data = stamps_ns[keep], np.stack(steps)[order[keep]]
    t = (stamps_ns - stamps_ns[0]) * 1e-9
    world, world_problem = _world(bag, world_topic, world_messages[-1]) if world_messages else (None, None)
    columns = {field: OBSERVATION_FIELDS.index(field) for field in OBSERVATION_FIELDS}
    runs = []
    for row, namespace in enumerate(found):
        if namespaces and namespace not in namespaces:
            continue
        truth, odom = (Trajectory(f'{topic} {robots[row]} {kind}', t, data[:, row, columns[f'{kind}_x']],
                                  data[:, row, columns[f'{kind}_y']],
                                  np.unwrap(_as_sent(data[:, row, columns[f'{kind}_yaw']])), stamps_ns)
                       for kind in ('truth', 'odom'))
        run = RunData(str(bag.path), namespace, truth, truth, odom, None, world, bag.closed_properly,
                      world_problem=world_problem)
        run.start_pose = start_pose(world, run.name, len(found)) if world is not None else None
        runs.append(run)
    return runs


def _as_sent(yaw: np.ndarray) -> np.ndarray:
    """Yaws as an Odometry message carries them (its quaternion's heading, `odometry_fields`)."""
    return np.array([yaw_from_quaternion(0.0, 0.0, *quaternion_from_yaw(value)) for value in yaw.tolist()])


def _checked_namespaces(bag: Bag, namespaces: Sequence[str] | None) -> list[str]:
    """The robots asked for (all recorded ones by default); BagError if the bag has none or not those."""
    found = robot_namespaces(bag)
    if not found:
        raise BagError(f'{bag.path}: no odometry: the bag has no {ODOMETRY} topic named '
                       f'{" or ".join(TRAJECTORY_TOPICS)}')
    for namespace in namespaces or ():
        if namespace not in found:
            raise BagError(f'{bag.path}: no odometry under namespace {namespace} (robots: {", ".join(found)})')
    return list(namespaces or found)


def _read_rows(bag: Bag, odometry: list[str], proximity: list[str],
               world_topic: str | None) -> tuple[dict[str, list], list[bytes]]:
    """The decoded rows of each odometry and proximity topic, and the world topic's messages, in one pass."""
    rows: dict[str, list] = {}
    handlers = {}
    for topic in odometry:
        rows[topic] = []
        handlers[topic] = (odometry_fields, rows[topic].append)
    for topic in proximity:
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
    return rows, world_messages


def start_pose(world: World, name: str, robots: int) -> tuple[float, float, float] | None:
    """Where robot `name` started in `world` (a one-robot bag's robot: the world's only one); None if not said."""
    for robot in world.robots:
        if robot.name == name:
            return robot.pose
    return world.robots[0].pose if robots == 1 and len(world.robots) == 1 else None


@contextmanager
def _cyclic_gc_paused() -> Iterator[None]:
    """Decoding keeps up to millions of small tuples alive; none is in a cycle, so the cyclic
    garbage collector would only rescan them over and over (much of the time on a big bag: benchmarks/bench_bag.py)."""
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
    """Odometry rows (stamp ns, x, y, yaw, v, w) sorted by stamp, one per stamp; t counted from `origin_ns`.

    A stamp seen twice is one step published twice: in lockstep the simulator sends its first step again when a
    controller still connecting has not answered it (`epuck_ros.lockstep`), and a step is one pose of the run."""
    stamps, x, y, yaw, _, _ = (np.array(column) for column in zip(*rows))
    stamps = stamps.astype(np.int64)
    order = np.argsort(stamps, kind='stable')
    order = order[np.concatenate(([True], np.diff(stamps[order]) != 0))]
    stamps = stamps[order]
    return Trajectory(topic, (stamps - origin_ns) * 1e-9, x[order], y[order], np.unwrap(yaw[order]), stamps)
