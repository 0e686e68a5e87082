"""The simulator's robot descriptions and TF tree (REP 105), as robot_state_publisher and a diff-drive base give them.

`/tf_static`: `world` -> each robot's `odom` at its start pose (odometry starts there at zero, so ground truth and
odometry sit in one tree), `base_link` -> every sensor frame of `epuck_ros.description` and -> `laser_scanner`, the
frame of the e-puck interface's `scan`. `/tf`, every step:
`odom` -> `base_link` from the encoders, and `base_link` -> each wheel at its encoder angle. `robot_description`
(latched) per robot, its links named as its frames. Frames and topics are the robot's own (`RobotPorts`).

tf2_msgs is not on PyPI: scripts/gen_tf2_msgs.sh builds it at set-up; where it cannot be imported the descriptions
are still published, and the simulator says once that there is no TF.
"""
from __future__ import annotations

from functools import partial

from geometry_msgs.msg import TransformStamped
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from epuck_ros.conversions import quaternion_from_yaw
from epuck_ros.description import WHEEL_LINKS, sensor_frames, urdf, wheel_offsets
from epuck_ros.epuck_interface import SCAN_FRAME, SCAN_FRAME_HEIGHT
from epuck_ros.model import RobotModel
from epuck_ros.ros.on_demand import OnDemand
from epuck_ros.ros.qos import LATCHED, deeper
from epuck_ros.ros.robot_ports import RobotPorts, quiet_publisher, topic_prefix
from epuck_ros.ros.serialized import Patch
from epuck_ros.simulation import Simulation

try:
    from tf2_msgs.msg import TFMessage
except ImportError:   # a pip install without scripts/gen_tf2_msgs.sh
    TFMessage = None

_CHANGING = (('translation.x', 'translation.y', 'rotation.z', 'rotation.w'), ('rotation.y', 'rotation.w'),
             ('rotation.y', 'rotation.w'))
_STEP_FIELDS = [field for index, paths in enumerate(_CHANGING) for field in
                [(f'transforms[{index}].header.stamp.sec', 'i'), (f'transforms[{index}].header.stamp.nanosec', 'I')]
                + [(f'transforms[{index}].transform.{path}', 'd') for path in paths]]
"""What changes in a robot's /tf message from one step to the next: odom -> base_link, then each wheel."""


def tf_available() -> bool:
    """Whether this installation has tf2_msgs (every ROS install; pip installs after scripts/gen_tf2_msgs.sh)."""
    return TFMessage is not None


class TfPorts:
    """Publishes every robot's description once and, if tf2_msgs imports, the static tree and each step's TF."""

    def __init__(self, node: Node, ports: list[RobotPorts], sim: Simulation, several: bool, stream_qos: QoSProfile,
                 latched_qos: QoSProfile, world_frame: str, model: RobotModel = RobotModel(),
                 demand: OnDemand | None = None) -> None:
        """`stream_qos`: that of the robots' step topics; /tf, one message per robot and step, keeps as many steps
        (reliable, as tf2_ros broadcasts), so that the simulator's acknowledgement window covers it too. `demand`:
        each robot's description is published only once its topic has a reader (`on_demand`)."""
        for robot in ports:
            topic = topic_prefix(robot.name, several) + 'robot_description'
            describe = partial(_describe, node, topic, latched_qos, model, _prefix(robot))
            if demand is None:
                describe()
            else:
                demand.add(node.resolve_topic_name(topic), describe)
        self._tf_pub = None
        self.stream_publishers = []
        """The publishers of every step, for the simulator's acknowledgement window (`ack_window`)."""
        if TFMessage is None:
            node.get_logger().info('tf2_msgs is not installed: no /tf and /tf_static (run scripts/gen_tf2_msgs.sh)')
            return
        static = []
        for robot, start in zip(ports, sim.world.robots):
            x, y, yaw = start.pose
            static.append(_transform(world_frame, robot.odom_frame, (x, y, 0.0), _yaw(yaw)))
            static += [_transform(robot.base_frame, _prefix(robot) + frame.name, frame.xyz, frame.quaternion())
                       for frame in sensor_frames(model)]
            static.append(_transform(robot.base_frame, _prefix(robot) + SCAN_FRAME, (0.0, 0.0, SCAN_FRAME_HEIGHT),
                                     _yaw(0.0)))   # the e-puck interface's `scan` (epuck_interface)
        # LATCHED is tf2_ros's StaticBroadcasterQoS (depth 1, reliable, transient local): late joiners get the tree
        quiet_publisher(node, TFMessage, '/tf_static', LATCHED).publish(TFMessage(transforms=static))
        self._tf_pub = quiet_publisher(node, TFMessage, '/tf', deeper(stream_qos, len(ports)))
        self.stream_publishers = [self._tf_pub]
        self._steps = []
        alike: dict[int, Patch] = {}   # frame ids as long, fields at the same offsets: one Patch built per length
        for robot in ports:
            transforms = [_transform(robot.odom_frame, robot.base_frame, (0.0, 0.0, 0.0), _yaw(0.0))]
            transforms += [_transform(robot.base_frame, _prefix(robot) + link, offset, (0.0, 0.0, 0.0, 1.0))
                           for link, offset in zip(WHEEL_LINKS, wheel_offsets(model))]
            msg, length = TFMessage(transforms=transforms), len(_prefix(robot))
            if length not in alike:
                alike[length] = Patch(msg, _STEP_FIELDS)
            self._steps.append(alike[length].like(msg))

    def publish(self, sim: Simulation, stamp: tuple[int, int]) -> None:
        """Each robot's odometry and wheel angles of this step, on /tf (nothing if nobody listens)."""
        if self._tf_pub is None or not self._tf_pub.get_subscription_count():
            return
        for patch, (x, y, yaw), (left, right) in zip(self._steps, sim.odom_pose.tolist(), sim.wheel_angles.tolist()):
            # a wheel turns about y: its quaternion (0, sin, 0, cos) has the numbers of a yaw's (0, 0, sin, cos)
            self._tf_pub.publish(patch.bytes((*stamp, x, y, *quaternion_from_yaw(yaw), *stamp,
                                              *quaternion_from_yaw(left), *stamp, *quaternion_from_yaw(right))))


def _prefix(robot: RobotPorts) -> str:
    """What the robot's frame ids start with (`epuck3/` in a swarm)."""
    return robot.base_frame.removesuffix('base_link')


def _yaw(yaw: float) -> tuple[float, float, float, float]:
    return 0.0, 0.0, *quaternion_from_yaw(yaw)


def _transform(parent: str, child: str, xyz: tuple[float, float, float],
               quaternion: tuple[float, float, float, float]) -> TransformStamped:
    msg = TransformStamped()
    msg.header.frame_id, msg.child_frame_id = parent, child
    msg.transform.translation.x, msg.transform.translation.y, msg.transform.translation.z = xyz
    (msg.transform.rotation.x, msg.transform.rotation.y, msg.transform.rotation.z,
     msg.transform.rotation.w) = quaternion
    return msg


def _describe(node: Node, topic: str, qos: QoSProfile, model: RobotModel, prefix: str) -> None:
    """A robot's description (its links named `<prefix>base_link`, ...), latched on `topic`."""
    quiet_publisher(node, String, topic, qos).publish(String(data=urdf(model, prefix)))
