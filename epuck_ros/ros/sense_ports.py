"""One robot's sense topics on the simulator node: camera/image_raw and camera/camera_info, ground_raw, light_raw,
imu (design.md, "Senses") and tof (the e-puck2's time-of-flight sensor as the e-puck's ROS interface has it: a
sensor_msgs/Range, `sensors.tof`); each sense is computed only while it is wanted.

Wanted means a subscriber on its topic that asks for it (so an echo, RViz or a controller just works), or the `senses`
parameter. A recorder's subscriber does not ask (`RECORDER_NODE`): it records a sense while something else asks for
it, so recording an IR-only run renders no camera (it rendered and recorded one every step, the bag several times as
large). A topic is published while its sense is wanted and it has a subscriber of either kind.
From SENSE_TOPICS_ON_DEMAND_FROM robots a topic's publisher is made only once a subscriber to it is in the graph
(`SensePorts`).
The node looks at the subscriber counts every SENSE_POLL wall seconds (`update_wants`), not every step: a swarm's
thousands of topics would cost more than its steps. A sense newly wanted is read at once from the current state and
its message of the current step published at once: a lockstep controller that has just subscribed waits for that
message before it answers the step, so the sense is sure to be read on the next step (the step protocol, see
epuck_ros/lockstep.py). Every message names its step: a header's stamp, or for the raw arrays the layout's label
(`conversions.stamp_label`). Messages are serialised once and patched each step (`serialized`), the image's pixels
copied into the tail of its CDR bytes.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping, Sequence
from functools import partial

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CameraInfo, Image, Imu, Range
from std_msgs.msg import Float64MultiArray, String

from epuck_ros.bag.steps import SENSES_ON_TOPIC, senses_on_text
from epuck_ros.description import IMU_FRAME
from epuck_ros.model import CAMERA_FOV, TOF_APERTURE, TOF_NAME
from epuck_ros.ros.on_demand import TOPICS_ON_DEMAND_FROM
from epuck_ros.ros.qos import SENSES_ON_QOS
from epuck_ros.ros.robot_ports import STAMP_FIELDS, frame_prefix, quiet_publisher, topic_prefix
from epuck_ros.conversions import stamp_from_seconds
from epuck_ros.ros.serialized import Patch, array_bytes, exact_cdr
from epuck_ros.sensors.camera import camera_matrix
from epuck_ros.sensors.imu import rates_from_gyro_values
from epuck_ros.sensors.tof import RANGE_LIMITS, range_from_value
from epuck_ros.simulation import Simulation


class SenseError(ValueError):
    """A sense the simulator does not have (the `senses` parameter); the message names it."""


SENSE_POLL = 0.5
"""Wall seconds between two looks at which sense topics have subscribers."""
SENSE_TOPICS = {'camera': 'camera/image_raw', 'ground': 'ground_raw', 'light': 'light_raw', 'imu': 'imu',
                'tof': TOF_NAME}
"""Each sense and the topic whose subscribers want it."""
SENSE_TOPICS_ON_DEMAND_FROM = TOPICS_ON_DEMAND_FROM
"""Robots from which the simulator makes a sense topic's publisher only once the topic has a reader
(`SensePorts`' on_demand), as every per-robot topic (`on_demand`)."""
_CAMERA_INFO = 'camera_info'
ON_DEMAND_TOPICS = {**SENSE_TOPICS, _CAMERA_INFO: 'camera/camera_info'}
"""Every sense topic of a robot by kind (the camera has two); `_TYPES`: their message types."""
_TYPES = {'camera': Image, _CAMERA_INFO: CameraInfo, 'ground': Float64MultiArray, 'light': Float64MultiArray,
          'imu': Imu, 'tof': Range}
RECORDER_NODE = 'recorder'
"""The node name of `record` (nodes/record_node.py): its subscribers record a sense topic without asking for it."""
_UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'
"""The node name the graph gives an endpoint whose node it has not heard of yet."""
IMU_FIELDS = STAMP_FIELDS + [(f'{vector}.{axis}', 'd') for vector in ('angular_velocity', 'linear_acceleration')
                             for axis in 'xyz']


def tof_range(frames: str) -> Range:
    """The `tof` topic's Range as webots_ros2's DistanceSensor plugin fills it (Ros2DistanceSensor.cpp): radiation type
    INFRARED (its type for every distance sensor), the aperture as field of view, the table's limits; frame `tof`."""
    msg = Range(radiation_type=Range.INFRARED, field_of_view=TOF_APERTURE, min_range=RANGE_LIMITS[0],
                max_range=RANGE_LIMITS[1])
    msg.header.frame_id = frames + TOF_NAME
    return msg


class ImagePatch:
    """An Image serialised once; `bytes(stamp, pixels)` puts the stamp and the pixels (the message's last field,
    uint8: no padding after it) into a copy."""

    def __init__(self, msg: Image) -> None:
        size = len(msg.data)
        msg.data = bytes(i % 251 for i in range(size))   # a pattern to find
        template = exact_cdr(msg)
        if template[len(template) - size:] != bytes(msg.data):
            raise ValueError('cannot locate the pixels in the serialised Image')
        self._offset = len(template) - size
        self._stamp = Patch(msg, STAMP_FIELDS)

    def bytes(self, stamp: tuple[int, int], pixels: bytes) -> bytes:
        buffer = bytearray(self._stamp.bytes(stamp))
        buffer[self._offset:] = pixels
        return bytes(buffer)


def camera_messages(frames: str, size: tuple[int, int]) -> tuple[ImagePatch, Patch]:
    """The camera's Image (rgb8) and CameraInfo in frame `<frames>camera`, serialised once."""
    width, height = size
    image = Image(height=height, width=width, encoding='rgb8', is_bigendian=0, step=3 * width)
    image.header.frame_id = frames + 'camera'
    image.data = bytes(3 * width * height)
    info = CameraInfo(height=height, width=width, distortion_model='plumb_bob', d=[0.0] * 5,
                      k=camera_matrix(width, height, CAMERA_FOV), r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
    k = info.k
    info.p = [k[0], 0.0, k[2], 0.0, 0.0, k[4], k[5], 0.0, 0.0, 0.0, 1.0, 0.0]
    info.header.frame_id = frames + 'camera'
    return ImagePatch(image), Patch(info, STAMP_FIELDS)


def readers_of(node: Node, publisher: Publisher | None, settled_counts: dict[str, tuple[int, int]],
               kind: str) -> tuple[int, int]:
    """How many readers `publisher`'s topic has, and how many of them ask for it: any reader but a recorder's
    (RECORDER_NODE). The graph is asked only when the number of matched readers changed (`settled_counts[kind]`, the
    last settled answer), until it shows that many with their nodes' names; meanwhile the readers known to ask are
    not counted fewer than before."""
    count = 0 if publisher is None else publisher.get_subscription_count()
    settled = settled_counts.get(kind)
    if settled is not None and settled[0] == count:
        return settled
    if count == 0:
        settled_counts[kind] = (0, 0)
        return 0, 0
    names = [info.node_name for info in node.get_subscriptions_info_by_topic(publisher.topic_name)]
    asking = sum(1 for name in names if name != RECORDER_NODE and not name.startswith(_UNKNOWN_NODE))
    if len(names) == count and not any(name.startswith(_UNKNOWN_NODE) for name in names):
        settled_counts[kind] = (count, asking)
    elif settled is not None:
        asking = max(asking, settled[1])
    return count, asking


class SensePorts:
    """The sense topics of robot `index`.

    `on_demand`: each topic's publisher is made only once a subscriber to it is in the graph (`offer`, which the
    node calls), not at start. A swarm's thousands of sense publishers were the largest part of its start-up and of
    its memory, for topics hardly any of its robots ever has a reader of; the price is that a topic without a reader
    is not in the graph (`ros2 topic list`, RViz's list by topic, a recorder of all topics do not see it), so a
    reader names its type. The node uses it from SENSE_TOPICS_ON_DEMAND_FROM robots."""

    taken: frozenset[str] = frozenset()
    """The kinds it subscribes to (none: every topic of it is published)."""

    def __init__(self, node: Node, index: int, name: str, several: bool, stream_qos: QoSProfile,
                 sim: Simulation, frames_prefix: str = '', on_demand: bool = False) -> None:
        self.index = index
        topics = topic_prefix(name, several)
        frames = frame_prefix(name, several, frames_prefix)
        width, height = sim.senses.camera_size
        self._node, self._qos = node, stream_qos
        self._prefix = topics
        self.topics = {kind: topics + topic for kind, topic in ON_DEMAND_TOPICS.items()}
        """Each of its topics (relative to the node's namespace) by kind: SENSE_TOPICS' and 'camera_info'."""
        self._publishers: dict[str, Publisher | None] = dict.fromkeys(ON_DEMAND_TOPICS)
        if not on_demand:
            for kind in ON_DEMAND_TOPICS:
                self.offer(kind)
        self._frames, self._size = frames, (width, height)
        self._made = False
        self._wanted = {kind: False for kind in SENSE_TOPICS}
        self._asking = {kind: 0 for kind in SENSE_TOPICS}
        self._readers: dict[str, tuple[int, int]] = {}
        """Per kind, (matched readers, readers that ask) as last settled by the graph (`_readers_of`)."""
        self.subscribed = {kind: False for kind in SENSE_TOPICS}
        """Per sense, whether its topic is published after each step: the sense is wanted and the topic read."""
        self._info_subscribed = False
        """The same for camera/camera_info: read, and asked for or the camera wanted."""
        self.publishing = False
        """Some sense topic of this robot is published: the node calls `publish` after each step."""
        self._senses_on: Publisher | None = None
        self._announced: list[str] = []
        """The topics `senses_on` said are published (made at its first message: most robots of a swarm never
        have one)."""

    def offers(self, kind: str) -> bool:
        """Whether the topic of `kind` has its publisher."""
        return self._publishers[kind] is not None

    def offer(self, kind: str) -> None:
        """The publisher of the topic of `kind` (a key of `topics`), made if it is not yet."""
        if self._publishers[kind] is None:
            self._publishers[kind] = quiet_publisher(self._node, _TYPES[kind], self.topics[kind], self._qos)

    def _make_messages(self) -> None:
        """The messages, serialised once, when a sense of this robot is first wanted (a swarm's robots mostly never
        are: making them for all would slow its start)."""
        frames = self._frames
        self._image, self._info = camera_messages(frames, self._size)
        imu = Imu()
        imu.header.frame_id = frames + IMU_FRAME
        imu.orientation_covariance[0] = -1.0   # REP 145: no orientation estimate
        self._imu = Patch(imu, IMU_FIELDS)
        self._tof = Patch(tof_range(frames), STAMP_FIELDS + [('range', 'f')])
        self._made = True

    def update_wants(self, want: Callable[[str, int, bool], None], forced: frozenset[str],
                     wanted: Callable[[str], bool] | None = None) -> list[str]:
        """Tell the simulation which of this robot's senses are wanted now (`forced`: by the parameter); the senses
        that have just got a reader that asks for them, or whose publication starts (the node publishes their
        current step at once: a lockstep controller that subscribed waits for that message). `wanted`: whether a
        sense is computed, whoever asked (the e-puck interface's topics ask too, `SenseFeeds`); by default what
        these topics ask."""
        readers = {kind: self._readers_of(kind) for kind in ON_DEMAND_TOPICS}
        new, computed = [], {}
        for kind in SENSE_TOPICS:
            count, asking = readers[kind]
            asks = asking > 0 or kind in forced
            if asks != self._wanted[kind]:
                self._wanted[kind] = asks
                want(kind, self.index, asks)
            computed[kind] = asks if wanted is None else wanted(kind)
            if asking > self._asking[kind] or (count and computed[kind] and not self.subscribed[kind]):
                new.append(kind)
            self._asking[kind] = asking
        self.follow(computed, {kind: count > 0 for kind, (count, _) in readers.items()}, readers[_CAMERA_INFO][1] > 0)
        return new

    def follow(self, wanted: Mapping[str, bool], read: Mapping[str, bool], info_asked: bool = False) -> None:
        """Publish, after each step, the topics of the `wanted` senses that are `read` (by kind, camera_info's
        with the camera's or when `info_asked`). A headless trial's bag (experiments/recording.py) follows what
        the simulation computes, as its recorder reads every topic."""
        for kind in SENSE_TOPICS:
            self.subscribed[kind] = read[kind] and wanted[kind]
        self._info_subscribed = read[_CAMERA_INFO] and (info_asked or wanted['camera'])
        self.publishing = self._info_subscribed or any(self.subscribed.values())
        if self.publishing and not self._made:
            self._make_messages()

    def announce(self, after: tuple[int, int], also: Iterable[str] = ()) -> None:
        """Say on `senses_on` which sense topics are published from the step after `after` on (called as that step
        is published), if that changed since it last said (`bag.steps.senses_on_text`): a recorder and `bag info`
        tell a sense that was off from one that was lost. `also`: the robot's other on-demand topics published (the
        e-puck interface's, `InterfacePorts.published_topics`)."""
        published = [ON_DEMAND_TOPICS[kind] for kind in SENSE_TOPICS if self.subscribed[kind]]
        published += [ON_DEMAND_TOPICS[_CAMERA_INFO]] if self._info_subscribed else []
        published += also
        if published == self._announced:
            return
        if self._senses_on is None:
            self._senses_on = quiet_publisher(self._node, String, self._prefix + SENSES_ON_TOPIC, SENSES_ON_QOS)
        self._announced = published
        self._senses_on.publish(String(data=senses_on_text(after, published)))

    def _readers_of(self, kind: str) -> tuple[int, int]:
        """How many readers the topic of `kind` has, and how many of them ask for it (`readers_of`)."""
        return readers_of(self._node, self._publishers[kind], self._readers, kind)

    def publish(self, sim: Simulation, stamp: tuple[int, int], kinds: Iterable[str] = SENSE_TOPICS) -> None:
        """This robot's sense messages of `kinds` that are published (their readings are those of this step)."""
        robot, senses, subscribed, publishers = self.index, sim.senses, self.subscribed, self._publishers
        for kind in kinds:
            if not subscribed[kind]:
                continue
            if kind == 'camera' and senses.images is not None:
                publishers['camera'].publish(self._image.bytes(stamp, senses.images[robot].tobytes()))
            elif kind == 'ground':
                publishers['ground'].publish(array_bytes(senses.ground_raw[robot].tolist(), stamp))
            elif kind == 'light':
                publishers['light'].publish(array_bytes(senses.light_raw[robot].tolist(), stamp))
            elif kind == 'imu':
                rates = rates_from_gyro_values(senses.gyro[robot]).tolist()
                publishers['imu'].publish(self._imu.bytes((*stamp, *rates, *senses.accelerometer[robot].tolist())))
            elif kind == 'tof':
                publishers['tof'].publish(self._tof.bytes((*stamp, float(range_from_value(senses.tof[robot])))))
        if self._info_subscribed and 'camera' in kinds:
            publishers[_CAMERA_INFO].publish(self._info.bytes(stamp))


class SenseFeeds:
    """Every robot's `SensePorts` on the node (and its `companions`' ports: the e-puck interface's), and which of
    them publish: the senses follow their topics' readers.

    `update_all` runs every SENSE_POLL wall seconds, `update_next` (one robot, in turn) after each step; both under
    the caller's lock, since the loop thread publishes. `offer_read_topics` makes the publishers of on-demand topics
    a reader appeared on, outside that lock (it asks the graph)."""

    def __init__(self, node: Node, sim: Simulation, stream_qos: QoSProfile, frames_prefix: str,
                 forced: frozenset[str], before_each: Callable[[], None],
                 companions: Sequence[Callable[..., SensePorts]] = ()) -> None:
        """`forced`: the senses the `senses` parameter asks for; `before_each` runs before each robot's ports are
        made (a swarm's take seconds: a stop request is honoured there); `companions`: other ports made as
        SensePorts is (the same arguments, the same protocol), whose topics ask for senses too."""
        several, on_demand = len(sim.names) > 1, len(sim.names) >= SENSE_TOPICS_ON_DEMAND_FROM
        self.ports: list[list[SensePorts]] = []
        """Per robot, its ports: the companions' first (their asks are then seen by the SensePorts' follow)."""
        for index, name in enumerate(sim.names):
            before_each()
            self.ports.append([make(node, index, name, several, stream_qos, sim, frames_prefix, on_demand)
                               for make in (*companions, SensePorts)])
        self._node, self._sim, self._forced = node, sim, forced
        self._unoffered = {node.resolve_topic_name(topic): (ports, kind) for groups in self.ports for ports in groups
                           for kind, topic in ports.topics.items() if not ports.offers(kind)}
        """The topics without a publisher (or subscription) yet (on demand), by their full names."""
        self._askers: dict[tuple[int, str], set[int]] = {}
        """Per (robot, sense), which of its ports ask for the sense (by position): it is computed while one does."""
        self._publishing: list[SensePorts] = []
        """The ports with a reader on some topic: their messages are published after each step."""
        self._unannounced: set[int] = set()
        """The robots whose senses may have changed since their `senses_on` last said: said with the next step (a
        change after the last step is none)."""
        self._last_stamp = (0, 0)
        self._turn = 0
        self._wants_changed = False

    def publish(self, stamp: tuple[int, int]) -> None:
        for robot in self._unannounced:
            *companions, senses = self.ports[robot]
            senses.announce(self._last_stamp, [topic for ports in companions for topic in ports.published_topics])
        self._unannounced.clear()
        self._last_stamp = stamp
        for ports in self._publishing:
            ports.publish(self._sim, stamp)

    def offer_read_topics(self, graph: Iterable[str]) -> None:
        """The publisher of each on-demand topic a reader has appeared on (the subscription of each one a writer
        has): `graph` is the node's one look at the graph's topics (a topic with only a reader is in it) instead of
        one question per topic."""
        if not self._unoffered:
            return
        for topic in graph:
            if topic in self._unoffered:
                ports, kind = self._unoffered[topic]
                if (self._node.count_publishers if kind in ports.taken else self._node.count_subscribers)(topic):
                    del self._unoffered[topic]
                    ports.offer(kind)

    def update_all(self) -> None:
        for robot in range(len(self.ports)):
            self._update(robot)

    def update_next(self) -> None:
        """One robot, in turn: at real_time_factor 0 the wall-clock poll alone would leave a controller that just
        enabled a sense without readings for hundreds of steps."""
        self._turn = (self._turn + 1) % len(self.ports)
        self._update(self._turn)

    def _update(self, robot: int) -> None:
        """One robot's wants; a sense just subscribed is published at once for the current step (see the module).
        When a sense's want changed, a second pass: the ports looked at before it follow it at once too."""
        wanted = self._sim.senses.wanted
        changed = False
        for _ in range(2):
            self._wants_changed = False
            for position, ports in enumerate(self.ports[robot]):
                was = ports.publishing
                new = ports.update_wants(partial(self._want, position), self._forced,
                                         lambda kind: bool(wanted[kind][robot]))
                changed |= ports.publishing != was
                if new and self._sim.steps:   # no step published yet: the first one will carry it
                    ports.publish(self._sim, stamp_from_seconds(self._sim.time), new)
            if not self._wants_changed:
                break
        self._unannounced.add(robot)
        if changed:
            self._publishing = [ports for groups in self.ports for ports in groups if ports.publishing]

    def _want(self, position: int, kind: str, robot: int, wanted: bool) -> None:
        """Robot `robot`'s ports at `position` ask for sense `kind` (or no longer): computed while any does."""
        askers = self._askers.setdefault((robot, kind), set())
        before = bool(askers)
        if wanted:
            askers.add(position)
        else:
            askers.discard(position)
        if bool(askers) != before:
            self._sim.senses.want(kind, [robot], bool(askers))
            self._wants_changed = True
