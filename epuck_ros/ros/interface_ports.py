"""One robot's topics of the e-puck's own ROS 2 interface on the simulator's node (`epuck_ros.epuck_interface`).

ps0..ps7 (Range), scan (LaserScan), ls0..ls7 (Illuminance), image_raw and camera_info (the physical robot's camera
names) are published, led0..led9 taken; our own topics stay as they are. They follow the sense mechanism of
`sense_ports` (`SenseFeeds` holds an `InterfacePorts` per robot beside its `SensePorts`): a topic is published
while it has a reader, and a topic that needs a sense (ls: light; image_raw: camera; scan: the ToF) asks for it
while a reader other than the recorder's reads it; from SENSE_TOPICS_ON_DEMAND_FROM robots a topic's publisher (an
LED's subscription) is made only once a reader (a writer) of it is in the graph. Every message carries the step's
stamp and is serialised once, then patched each step (`serialized`). The LEDs set what the controller's `leds`
carries (the ten values as Webots' LED.set takes them), which the view draws.
"""
from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from functools import partial

from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CameraInfo, Illuminance, Image, LaserScan, Range
from std_msgs.msg import Bool, Int32, Int32MultiArray

from epuck_ros import epuck_interface as iface
from epuck_ros.ir_sensor import distance_from_raw
from epuck_ros.model import RobotModel
from epuck_ros.ros.qos import LED_QOS
from epuck_ros.ros.robot_ports import STAMP_FIELDS, frame_prefix, quiet_publisher, topic_prefix
from epuck_ros.ros.sense_ports import ImagePatch, camera_messages, readers_of
from epuck_ros.ros.serialized import Patch
from epuck_ros.sensors.tof import range_from_value
from epuck_ros.simulation import Simulation

_SENSE_OF = {**dict.fromkeys(iface.IR_TOPICS), iface.SCAN_TOPIC: 'tof', **dict.fromkeys(iface.LIGHT_TOPICS, 'light'),
             'image_raw': 'camera', 'camera_info': None}
"""Each published topic (its kind) and the simulation's sense it needs computed (None: none, the IR ring is always
read)."""
_ASKS = {**dict.fromkeys(iface.IR_TOPICS, ('ir',)), iface.SCAN_TOPIC: ('ir', 'tof'),
         **dict.fromkeys(iface.LIGHT_TOPICS, ('light',)), 'image_raw': ('camera',), 'camera_info': ('camera_info',)}
"""What a reader that asks asks for: a sense of the simulation (`_SENSES`), or 'ir' / 'camera_info', this robot's
IR topics or its camera_info published."""
_SENSES = ('tof', 'light', 'camera')
_TYPES = {**dict.fromkeys(iface.IR_TOPICS, Range), iface.SCAN_TOPIC: LaserScan,
          **dict.fromkeys(iface.LIGHT_TOPICS, Illuminance), 'image_raw': Image, 'camera_info': CameraInfo}
INTERFACE_TOPICS = tuple(_TYPES)
"""The kinds of the topics it publishes."""
_SCAN_FIELDS = STAMP_FIELDS + [(f'ranges[{slot}]', 'f') for slot in range(len(iface.SCAN_SLOTS))]


class InterfacePorts:
    """The e-puck interface's topics of robot `index`; the same protocol as `SensePorts` for `SenseFeeds`."""

    def __init__(self, node: Node, index: int, name: str, several: bool, stream_qos: QoSProfile,
                 sim: Simulation, frames_prefix: str = '', on_demand: bool = False,
                 model: RobotModel = RobotModel()) -> None:
        self.index = index
        topics = topic_prefix(name, several)
        self._node, self._qos, self._model = node, stream_qos, model
        self._frames, self._size, self._time_step = frame_prefix(name, several, frames_prefix), \
            sim.senses.camera_size, sim.time_step
        self.topics = {kind: topics + kind for kind in (*_TYPES, *iface.LED_TOPICS)}
        """Each of its topics (relative to the node's namespace) by kind (the kind is the interface's name)."""
        self.taken = frozenset(iface.LED_TOPICS)
        """The kinds it subscribes to: on demand, made once a writer of the topic is in the graph."""
        self._publishers: dict[str, Publisher | None] = dict.fromkeys(_TYPES)
        self._subscriptions: dict[str, object] = {}
        self._leds = [0] * len(iface.LED_TOPICS)
        self._leds_publisher: Publisher | None = None
        self._leds_topic = topics + 'leds'
        if not on_demand:
            for kind in self.topics:
                self.offer(kind)
        self._readers: dict[str, tuple[int, int]] = {}
        self._asked = dict.fromkeys((*_SENSES, 'ir', 'camera_info'), False)
        """What its readers that ask ask for (`_ASKS`)."""
        self._asking: dict[str, int] = {}
        self._counts: list[int] = []
        self._computed: list[bool] | None = None
        self._settled = False
        """The readers' counts and the senses' states `update_wants` last followed, and whether the graph had shown
        every reader's node by then."""
        self._published: list[str] = []
        """The kinds published after each step: read, and their sense computed."""
        self._patches: dict[str, Patch | ImagePatch] = {}
        self.publishing = False
        """Some topic of this robot is published: the node calls `publish` after each step."""

    def offers(self, kind: str) -> bool:
        return (self._publishers.get(kind) if kind in _TYPES else self._subscriptions.get(kind)) is not None

    def offer(self, kind: str) -> None:
        """The publisher (an LED's subscription) of the topic of `kind`, made if it is not yet."""
        if kind in self.taken:
            if kind not in self._subscriptions:
                index = iface.LED_TOPICS.index(kind)
                msg_type = Bool if index in iface.BOOL_LEDS else Int32
                self._subscriptions[kind] = self._node.create_subscription(
                    msg_type, self.topics[kind], partial(self._on_led, index), 10)
        elif self._publishers[kind] is None:
            self._publishers[kind] = quiet_publisher(self._node, _TYPES[kind], self.topics[kind], self._qos)

    def _on_led(self, index: int, msg: Bool | Int32) -> None:
        """An LED's message: the robot's `leds` carry it from now on (published at once, latched, as a controller
        that sets its LEDs publishes them)."""
        value = iface.led_value(index, msg.data)
        if value == self._leds[index] and self._leds_publisher is not None:
            return
        self._leds[index] = value
        if self._leds_publisher is None:
            self._leds_publisher = quiet_publisher(self._node, Int32MultiArray, self._leds_topic, LED_QOS)
        self._leds_publisher.publish(Int32MultiArray(data=self._leds))

    # --- who reads -------------------------------------------------------------------------------------------

    def update_wants(self, want: Callable[[str, int, bool], None], forced: frozenset[str],
                     wanted: Callable[[str], bool] | None = None) -> list[str]:
        """Ask for the senses its topics need while a reader that asks reads them; follow the readers (and
        `wanted`: whether a sense is computed, whoever asked). The kinds to publish at once: newly published, or
        with one more reader that asks (a lockstep controller that just subscribed waits for this step's)."""
        counts = [0 if publisher is None else publisher.handle.get_subscription_count()   # rclpy's own call,
                  for publisher in self._publishers.values()]                             # without its lock
        computed = [wanted(sense) for sense in _SENSES] if wanted is not None else None
        if counts == self._counts and computed == self._computed and self._settled:
            return []   # nothing changed: the simulator looks every step, at a few microseconds
        self._counts, self._computed = counts, computed
        readers = {kind: self._readers_of(kind) for kind in _TYPES}
        self._settled = all(self._readers.get(kind, (0,))[0] == count for kind, (count, _) in readers.items())
        asked = dict.fromkeys(self._asked, False)
        for kind, (_, asking) in readers.items():
            for what in _ASKS[kind] if asking else ():
                asked[what] = True
        for sense, on in asked.items():
            if on != self._asked[sense] and sense in _SENSES:
                want(sense, self.index, on)
        self._asked = asked
        more = [kind for kind, (_, asking) in readers.items() if asking > self._asking.get(kind, 0)]
        self._asking = {kind: asking for kind, (_, asking) in readers.items()}
        new = self.follow(wanted or (lambda sense: asked[sense] or sense in forced),
                          {kind: count > 0 for kind, (count, _) in readers.items()})
        return [kind for kind in self._published if kind in new or kind in more]

    def follow(self, wanted: Callable[[str], bool], read: Mapping[str, bool]) -> list[str]:
        """Publish, after each step, the topics that are `read` and needed: the IR topics while a reader that asks
        reads one of them (as a sense's topic, so a recorder alone records none), ls and image_raw while their
        sense is computed, scan while both hold, camera_info while asked or the camera is computed. A headless
        trial's bag: every topic is read, and follows what the simulation computes. The kinds newly published."""
        asked = self._asked
        needed = {kind: asked['ir'] if _SENSE_OF[kind] is None else
                  (asked['ir'] and wanted('tof')) if kind == iface.SCAN_TOPIC else wanted(_SENSE_OF[kind])
                  for kind in _TYPES}
        needed['camera_info'] = asked['camera_info'] or wanted('camera')
        was = set(self._published)
        self._published = [kind for kind in _TYPES if read[kind] and needed[kind]]
        self.publishing = bool(self._published)
        return [kind for kind in self._published if kind not in was]

    @property
    def published_topics(self) -> list[str]:
        """Its topics published after each step, relative to the robot's (what `senses_on` says beside the senses)."""
        return list(self._published)

    def _readers_of(self, kind: str) -> tuple[int, int]:
        return readers_of(self._node, self._publishers[kind], self._readers, kind)

    # --- publishing --------------------------------------------------------------------------------------------

    def _patch(self, kind: str) -> Patch | ImagePatch:
        """The message of `kind`, made when first published (a swarm's robots mostly never are)."""
        patch = self._patches.get(kind)
        if patch is None:
            patch = self._patches[kind] = self._make(kind)
        return patch

    def _make(self, kind: str) -> Patch | ImagePatch:
        frames = self._frames
        if kind in iface.IR_TOPICS:
            msg = Range(radiation_type=Range.INFRARED, field_of_view=iface.IR_FIELD_OF_VIEW,
                        min_range=iface.IR_MIN_RANGE, max_range=iface.IR_MAX_RANGE)
            msg.header.frame_id = frames + kind
            return Patch(msg, STAMP_FIELDS + [('range', 'f')])
        if kind in iface.LIGHT_TOPICS:
            msg = Illuminance()
            msg.header.frame_id = frames + kind
            return Patch(msg, STAMP_FIELDS + [('illuminance', 'd')])
        if kind == iface.SCAN_TOPIC:
            msg = LaserScan(angle_min=iface.SCAN_ANGLE_MIN, angle_max=iface.SCAN_ANGLE_MAX,
                            angle_increment=iface.SCAN_ANGLE_INCREMENT, scan_time=self._time_step,
                            range_min=iface.SCAN_RANGE_MIN, range_max=iface.SCAN_RANGE_MAX,
                            ranges=[0.0] * len(iface.SCAN_SLOTS))
            msg.header.frame_id = frames + iface.SCAN_FRAME
            return Patch(msg, _SCAN_FIELDS)
        image, info = camera_messages(frames, self._size)
        return image if kind == 'image_raw' else info

    def ir_ranges(self, sim: Simulation) -> list[float]:
        """ps0..ps7's ranges of this step: the raw values back through the table, as both sources publish them."""
        return distance_from_raw(sim.ir_raw[self.index], self._model.ir_table).tolist()

    def publish(self, sim: Simulation, stamp: tuple[int, int], kinds: Iterable[str] | None = None) -> None:
        """This robot's interface messages of `kinds` (default: every one published), of this step."""
        kinds = self._published if kinds is None else [kind for kind in kinds if kind in self._published]
        if not kinds:
            return
        robot, publishers = self.index, self._publishers
        ir = self.ir_ranges(sim) if any(kind in iface.IR_TOPICS or kind == iface.SCAN_TOPIC for kind in kinds) \
            else None
        for kind in kinds:
            if kind in iface.IR_TOPICS:
                data = self._patch(kind).bytes((*stamp, ir[iface.IR_TOPICS.index(kind)]))
            elif kind in iface.LIGHT_TOPICS:
                value = float(sim.senses.light_raw[robot, iface.LIGHT_TOPICS.index(kind)])
                data = self._patch(kind).bytes((*stamp, value))
            elif kind == iface.SCAN_TOPIC:
                tof = float(range_from_value(float(sim.senses.tof[robot])))
                data = self._patch(kind).bytes((*stamp, *iface.scan_ranges(ir, tof)))
            elif kind == 'image_raw':
                data = self._patch(kind).bytes(stamp, sim.senses.images[robot].tobytes())
            else:
                data = self._patch(kind).bytes(stamp)
            publishers[kind].publish(data)
