"""One robot's ports on the simulator node, as turtlesim's Turtle owns its topics.

`RobotPorts` holds everything of one robot that ROS sees: its command subscriptions, its step publishers with
their reusable messages and its frame ids; lockstep's bookkeeping is `epuck_ros.lockstep`'s. With
one robot every name is the historical one (`odom`, frame `base_link`, `frame_prefix` in front); with several,
each robot's topics live under its name relative to the simulator's namespace (`epuck3/odom`) and its frames
are `epuck3/odom`, `epuck3/base_link`, `epuck3/ps0`... (stage_ros2's convention).
"""
from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState, Range
from std_msgs.msg import Float64MultiArray, UInt32

from epuck_ros.conversions import nanoseconds_from_stamp, quaternion_from_yaw
from epuck_ros.description import JOINT_NAMES
from epuck_ros.lockstep import Controller
from epuck_ros.model import SENSOR_NAMES, RobotModel
from epuck_ros.ros.qos import deeper
from epuck_ros.ros.on_demand import OnDemand
from epuck_ros.ros.serialized import PatchCache, array_bytes, array_values
from epuck_ros.simulation import Simulation

WORLD_FRAME = 'world'

# Diagonal covariances (x, y, z, roll, pitch, yaw): the planar robot knows nothing of z, roll and
# pitch (a large variance says so, as REP 105 users expect); x, y and yaw are of the order of
# the encoder quantisation (2π/1000 rad · 0.02 m ≈ 1.3e-4 m per tick).
_UNKNOWN = 1e6
POSE_COVARIANCE = [1e-6, 1e-6, _UNKNOWN, _UNKNOWN, _UNKNOWN, 1e-5]
TWIST_COVARIANCE = [1e-5, 1e-5, _UNKNOWN, _UNKNOWN, _UNKNOWN, 1e-4]

WARN_PERIOD = 1.0
"""Seconds between two warnings about refused commands."""
STAMP_FIELDS = [('header.stamp.sec', 'i'), ('header.stamp.nanosec', 'I')]
ODOMETRY_FIELDS = STAMP_FIELDS + [
    ('pose.pose.position.x', 'd'), ('pose.pose.position.y', 'd'), ('pose.pose.orientation.z', 'd'),
    ('pose.pose.orientation.w', 'd'), ('twist.twist.linear.x', 'd'), ('twist.twist.angular.z', 'd')]
"""What changes in an Odometry from one step to the next (the rest is serialised once)."""

CommandHandler = Callable[[int, str, str, float, float, 'int | None'], None]
"""(robot index, topic, 'wheels' or 'twist', first value, second value, the step it answers in nanoseconds or None
when it names none): what the node does with a command."""


MATCH_COLUMNS = 7
"""A robot's matched peers, by column: readers of odom, ground_truth, ir_raw, proximity, joint_states (READERS), then
the controllers on wheel_cmd and cmd_vel (CONTROLLERS)."""
READERS, CONTROLLERS = slice(0, 5), slice(5, 7)
STEP_TOPICS = ('odom', 'ground_truth', 'ir_raw', 'proximity', 'joint_states')
"""A robot's step topics, by READERS column; `_STEP_TYPES`: their message types."""
_STEP_TYPES = (Odometry, Odometry, Float64MultiArray, Range, JointState)


class Matched:
    """How many peers an endpoint has matched, kept from its matched events in a column of `counts` instead of asked
    at every step: asking costs 1.2 us a call, and a step asked each robot's five publishers and two command
    subscriptions (0.4 ms a step at 50 robots, a quarter of a step at 20x real time; 8 ms at 1,000), where a node's
    robots' counts in one array are read at once (`SimNode._driven`, `_publish`). `read` asks the middleware itself:
    before the first step and for a re-sent one, so a reader matched by then is served from that very step, however
    far the executor thread is behind with the events."""

    def __init__(self, counts: np.ndarray, column: int) -> None:
        self._counts, self._column = counts, column
        self._ask: Callable[[], int] = lambda: 0

    def on_matched(self, status: object) -> None:
        self._counts[self._column] = status.current_count

    def bind(self, ask: Callable[[], int]) -> None:
        self._ask = ask
        self.read()

    def read(self) -> None:
        self._counts[self._column] = self._ask()


def topic_prefix(name: str, several: bool) -> str:
    """What a robot's topic names start with: nothing for a lone robot (today's names), else `<name>/`."""
    return f'{name}/' if several else ''


def frame_prefix(name: str, several: bool, prefix: str = '') -> str:
    """What a robot's frame ids start with: `prefix` for a lone robot, else `<prefix><name>/`."""
    return prefix + topic_prefix(name, several)


class RobotPorts:
    """The topics of robot `index`: publishes its step messages, hands its commands to `on_command`."""

    def __init__(self, node: Node, index: int, name: str, several: bool, stream_qos: QoSProfile,
                 latched_qos: QoSProfile, on_command: CommandHandler, frames_prefix: str = '',
                 cmd_vel_stamped: bool = False, model: RobotModel = RobotModel(),
                 patches: PatchCache | None = None, matches: np.ndarray | None = None,
                 demand: OnDemand | None = None) -> None:
        """`patches`: shared by the robots of a node, so that each robot's messages are located from the first
        robot's of the same layout (`PatchCache`); `matches`: this robot's row of the node's matched counts
        (MATCH_COLUMNS integers, see `Matched`); `demand`: each topic is made only once someone reads it (a
        publisher) or writes it (a subscription), by `demand` (see `on_demand`), instead of now."""
        self.index, self.name = index, name
        topics = topic_prefix(name, several)
        frames = frame_prefix(name, several, frames_prefix)
        self.odom_frame, self.base_frame = frames + 'odom', frames + 'base_link'
        world_frame = frames_prefix + WORLD_FRAME  # shared by all robots, as are the world's markers
        self._on_command = on_command
        self._node, self._logger = node, node.get_logger()
        self._stamped = cmd_vel_stamped
        self._make_messages(frames, world_frame, model, patches or PatchCache())

        self.matches = np.zeros(MATCH_COLUMNS, dtype=np.int64) if matches is None else matches
        self._matched = [Matched(self.matches, column) for column in range(MATCH_COLUMNS)]
        self._publishers: list[Publisher | None] = [None] * len(STEP_TOPICS)
        """The step publishers by READERS column, once made."""
        self._collisions_pub: Publisher | None = None
        self._collisions = 0
        self._twist_sub: Subscription | None = None
        self._wheels_sub: Subscription | None = None
        qos = {topic: stream_qos for topic in STEP_TOPICS}
        qos['proximity'] = deeper(stream_qos, len(SENSOR_NAMES))   # proximity sends eight messages per step
        makers = {topic: partial(self._make_step_publisher, column, qos[topic])
                  for column, topic in enumerate(STEP_TOPICS)}
        makers['collisions'] = partial(self._make_collisions, latched_qos)
        commands = {'cmd_vel': partial(self._make_twist, cmd_vel_stamped), 'wheel_cmd': self._make_wheels}
        self.topics = {topic: topics + topic for topic in (*makers, *commands)}
        """Each of its topics (relative to the node's namespace) by its name under the robot."""
        for topic, make in {**makers, **commands}.items():
            if demand is None:
                make()
            else:
                demand.add(node.resolve_topic_name(self.topics[topic]), make, by_writer=topic in commands)

    @property
    def stream_publishers(self) -> list[Publisher]:
        """The step publishers made so far (the simulator's acknowledgement window looks at them)."""
        return [publisher for publisher in self._publishers if publisher is not None]

    def _make_step_publisher(self, column: int, qos: QoSProfile) -> None:
        self._publishers[column] = quiet_publisher(self._node, _STEP_TYPES[column], self.topics[STEP_TOPICS[column]],
                                                   qos, self._matched[column])

    def _make_collisions(self, qos: QoSProfile) -> None:
        """The latched count of contacts, with the count so far."""
        self._collisions_pub = quiet_publisher(self._node, UInt32, self.topics['collisions'], qos)
        self.publish_collisions(self._collisions)

    def _make_twist(self, stamped: bool) -> None:
        twist = self._matched[CONTROLLERS.start + 1]
        events = {'event_callbacks': SubscriptionEventCallbacks(matched=twist.on_matched)}
        if stamped:
            self._twist_sub = self._node.create_subscription(TwistStamped, self.topics['cmd_vel'],
                                                             self._stamped_twist, 10, **events)
        else:
            self._twist_sub = self._node.create_subscription(Twist, self.topics['cmd_vel'], self._twist, 10, **events)
        twist.bind(self._twist_sub.get_publisher_count)

    def _make_wheels(self) -> None:
        wheels = self._matched[CONTROLLERS.start]
        self._wheels_sub = self._node.create_subscription(
            Float64MultiArray, self.topics['wheel_cmd'], self._wheels, 10, raw=True,
            event_callbacks=SubscriptionEventCallbacks(matched=wheels.on_matched))
        wheels.bind(self._wheels_sub.get_publisher_count)

    def _make_messages(self, frames: str, world_frame: str, model: RobotModel, patches: PatchCache) -> None:
        """Each step message is serialised once; a step only patches its numbers in (see `serialized`). A robot's
        frame ids are as long as another's when their names are: the layout of their messages."""
        layout = len(frames)
        odom = Odometry()
        odom.header.frame_id = self.odom_frame
        odom.child_frame_id = self.base_frame
        odom.pose.covariance = _diagonal(POSE_COVARIANCE)
        odom.twist.covariance = _diagonal(TWIST_COVARIANCE)
        self._odom = patches.patch(odom, ODOMETRY_FIELDS, ('odom', layout))
        truth = Odometry()
        truth.header.frame_id = world_frame
        truth.child_frame_id = self.base_frame
        self._truth = patches.patch(truth, ODOMETRY_FIELDS, ('truth', layout))
        self._ranges = []
        for sensor in SENSOR_NAMES:
            msg = Range()
            msg.header.frame_id = frames + sensor
            msg.radiation_type = Range.INFRARED
            msg.field_of_view = model.ir_aperture
            msg.min_range = 0.0
            msg.max_range = model.ir_range
            self._ranges.append(patches.patch(msg, STAMP_FIELDS + [('range', 'f')], layout))
        joints = JointState(name=JOINT_NAMES, position=[0.0, 0.0], velocity=[0.0, 0.0])
        self._joints = patches.patch(joints, STAMP_FIELDS + [('position[0]', 'd'), ('position[1]', 'd'),
                                                             ('velocity[0]', 'd'), ('velocity[1]', 'd')], None)

    # --- commands ---------------------------------------------------------------------------------------

    def _twist(self, msg: Twist) -> None:
        self._on_command(self.index, self._twist_sub.topic_name, 'twist', msg.linear.x, msg.angular.z, None)

    def _stamped_twist(self, msg: TwistStamped) -> None:
        """A TwistStamped answers the step its header names (as Jazzy's diff_drive_controller takes cmd_vel)."""
        twist, stamp = msg.twist, msg.header.stamp
        self._on_command(self.index, self._twist_sub.topic_name, 'twist', twist.linear.x, twist.angular.z,
                         nanoseconds_from_stamp(stamp.sec, stamp.nanosec))

    def _wheels(self, data: bytes) -> None:
        read = array_values(data)  # received as bytes: see `serialized`
        if read is None or len(read[0]) != 2:
            got = 'bytes that are no Float64MultiArray' if read is None else f'{len(read[0])} values'
            self._logger.warning(f'{self._wheels_sub.topic_name} refused: data must be [left, right] rad/s, got {got}',
                                 throttle_duration_sec=WARN_PERIOD)
            return
        (left, right), stamp = read
        self._on_command(self.index, self._wheels_sub.topic_name, 'wheels', left, right,
                         None if stamp is None else nanoseconds_from_stamp(*stamp))

    def read_matches(self) -> None:
        """Ask the middleware now who is matched (see `Matched`)."""
        for matched in self._matched:
            matched.read()

    @property
    def command_topics(self) -> tuple[str, str]:
        """The fully qualified topics of its commands (wheel_cmd, cmd_vel): what a declaration names (also before
        their subscriptions are made, on demand)."""
        return self._node.resolve_topic_name(self.topics['wheel_cmd']), \
            self._node.resolve_topic_name(self.topics['cmd_vel'])

    def controller(self, declared: Controller | None) -> Controller:
        """What the graph says of its controller: only plain Twist publishers cannot answer by name; else it is
        what it `declared` (also once it has left the graph: its goodbye). A subscription not made yet (on demand)
        has no publisher."""
        wheels, twists = (0 if sub is None else sub.get_publisher_count()
                          for sub in (self._wheels_sub, self._twist_sub))
        if twists and not (wheels or self._stamped):
            return Controller.UNNAMING
        return declared or Controller.UNDECLARED

    def publishers(self) -> str:
        """The publishers of its commands, as the graph shows them (node, topic, endpoint GID)."""
        found = [f'{info.node_namespace.rstrip("/")}/{info.node_name} on {topic} '
                 f'(gid {bytes(info.endpoint_gid).hex()})'
                 for topic in self.command_topics for info in self._node.get_publishers_info_by_topic(topic)]
        return ', '.join(found) or 'none left on the graph'

    # --- publishing -------------------------------------------------------------------------------------

    def publish(self, sim: Simulation, stamp: tuple[int, int]) -> None:
        """This robot's step messages (not `/clock`, which the node sends last); topics nobody reads are skipped.

        `stamp` is (sec, nanosec) of the step."""
        robot = self.index
        odom, truth, raw, ranges, joints, _, _ = self.matches.tolist()
        odom_pub, truth_pub, raw_pub, range_pub, joints_pub = self._publishers   # matched: made
        if odom:
            odom_pub.publish(self._odom.bytes(_odometry(stamp, sim.odom_pose[robot], sim.odom_twist[robot])))
        if truth:
            truth_pub.publish(self._truth.bytes(_odometry(stamp, sim.true_pose[robot], sim.true_twist[robot])))
        if raw:
            raw_pub.publish(array_bytes(sim.ir_raw[robot].tolist(), stamp))
        if ranges:
            for patch, value in zip(self._ranges, sim.ir_range[robot].tolist()):
                range_pub.publish(patch.bytes((*stamp, value)))
        if joints:
            joints_pub.publish(self._joints.bytes(
                (*stamp, *sim.wheel_angles[robot].tolist(), *sim.wheel_speeds[robot].tolist())))

    def publish_collisions(self, count: int) -> None:
        """The robot's count of contacts, latched (kept for its topic's first reader, on demand)."""
        self._collisions = count
        if self._collisions_pub is not None:
            self._collisions_pub.publish(UInt32(data=count))


def quiet_publisher(node: Node, msg_type: type, topic: str, qos: QoSProfile, matched: Matched | None = None
                    ) -> Publisher:
    """A publisher without rclpy's default QoS-event handlers; with `matched`, that counts its readers.

    rclpy gives every publisher two event handlers (incompatible QoS, incompatible type) that sit in the
    executor's wait set, which it rebuilds in Python on every wait: with six publishers per robot they were most
    of the executor's work per received command. A reader with an incompatible QoS still hears about it: rclpy
    warns on the subscription's side."""
    publisher = node.create_publisher(msg_type, topic, qos, event_callbacks=PublisherEventCallbacks(
        matched=None if matched is None else matched.on_matched, use_default_callbacks=False))
    if matched is not None:
        matched.bind(publisher.get_subscription_count)
    return publisher


def _diagonal(values: list[float]) -> list[float]:
    matrix = [0.0] * 36
    for i, value in enumerate(values):
        matrix[7 * i] = value
    return matrix


def _odometry(stamp: tuple[int, int], pose: np.ndarray, twist: np.ndarray) -> tuple[float | int, ...]:
    """The values of ODOMETRY_FIELDS: a planar pose's quaternion is a rotation about z."""
    x, y, yaw = pose.tolist()
    return (*stamp, x, y, *quaternion_from_yaw(yaw), *twist.tolist())
