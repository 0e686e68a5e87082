"""`sim`: the e-puck simulator node — a thin ROS 2 shell around `epuck_ros.simulation.Simulation`.

The simulation steps in its own thread, paced by `real_time_factor` against the wall clock
(0 = as fast as the machine can go), and is the source of `/clock`; the executor thread only
receives commands and service calls. Every message of a step carries that step's simulated time.
"""
from __future__ import annotations

import math
import os
import threading
import time

import rclpy
import yaml
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist, TwistStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, Range
from std_msgs.msg import Float64MultiArray, String, UInt32
from std_srvs.srv import Empty

from epuck_ros.model import SENSOR_NAMES, RobotModel
from epuck_ros.nodes.spinning import spin_until_shutdown
from epuck_ros.simulation import CommandError, Simulation, StepEvents
from epuck_ros.world import World, WorldError, default_world, load_world

JOINT_NAMES = ['left_wheel_joint', 'right_wheel_joint']

# Diagonal covariances (x, y, z, roll, pitch, yaw): the planar robot knows nothing of z, roll and
# pitch (a large variance says so, as REP 105 users expect); x, y and yaw are of the order of
# the encoder quantisation (2π/1000 rad · 0.02 m ≈ 1.3e-4 m per tick).
_UNKNOWN = 1e6
POSE_COVARIANCE = [1e-6, 1e-6, _UNKNOWN, _UNKNOWN, _UNKNOWN, 1e-5]
TWIST_COVARIANCE = [1e-5, 1e-5, _UNKNOWN, _UNKNOWN, _UNKNOWN, 1e-4]
PUBLISHER_HISTORY_STEPS = 300
LOCKSTEP_START_RESENDS = 10
WARN_PERIOD = 1.0
"""Seconds between two warnings about the same kind of refused command."""


def _diagonal(values: list[float]) -> list[float]:
    matrix = [0.0] * 36
    for i, value in enumerate(values):
        matrix[7 * i] = value
    return matrix


def _float_param(description: str, low: float, high: float, read_only: bool = False) -> ParameterDescriptor:
    return ParameterDescriptor(
        description=description, read_only=read_only,
        floating_point_range=[FloatingPointRange(from_value=low, to_value=high, step=0.0)])


def _flag(description: str, read_only: bool = True) -> ParameterDescriptor:
    return ParameterDescriptor(description=description, read_only=read_only)


PARAMETERS: dict[str, tuple[object, ParameterDescriptor]] = {
    'time_step': (0.032, _float_param(
        'simulated seconds per step (Webots basicTimeStep is 32 ms)', 0.001, 1.0, read_only=True)),
    'real_time_factor': (1.0, _float_param('simulated seconds per wall second; 0 = as fast as possible', 0.0, 1e4)),
    'paused': (False, _flag('while true, simulated time stands still (nothing is stepped or published)', False)),
    'pause_at': (0.0, _float_param(
        'simulated time (s) at which the simulation pauses by itself, exactly; 0 = never', 0.0, 1e9)),
    'lockstep': (False, _flag(
        'step only once a command has arrived since the last step (or after lockstep_timeout): runs with one '
        'controller are the same whatever the load of the machine')),
    'lockstep_timeout': (1.0, _float_param(
        'wall seconds a lockstep simulation waits for a command before stepping anyway', 0.001, 60.0,
        read_only=True)),
    'world': ('', _flag('path to a world YAML file; empty = the built-in 1 m x 1 m arena')),
    'seed': (0, ParameterDescriptor(
        description='seed of every random draw: same seed, same run', read_only=True,
        integer_range=[IntegerRange(from_value=0, to_value=2**31 - 1, step=1)])),
    'noise': (True, _flag('IR sensor noise (Webots lookup table, relative Gaussian) on or off')),
    'cmd_timeout': (0.5, _float_param(
        'simulated seconds without a command before the robot stops; 0 = never', 0.0, 3600.0)),
    'cmd_vel_stamped': (False, _flag('subscribe cmd_vel as geometry_msgs/TwistStamped instead of Twist')),
    'frame_prefix': ('', _flag('prefix of every frame_id (e.g. "robot1/") for several robots in one TF tree')),
}
"""The simulator's parameters: name -> (default, descriptor). `bringup` routes `-p` assignments with it."""


class Pacer:
    """Sleeps so that simulated time runs `factor` times wall time (factor 0: no sleep at all)."""

    FALL_BEHIND = 0.5
    """Wall seconds behind schedule after which pacing starts afresh instead of bursting to catch up."""

    def __init__(self) -> None:
        self._origin: tuple[float, float, float] | None = None  # wall time, sim time, factor

    def restart(self) -> None:
        self._origin = None

    def wait(self, sim_time: float, factor: float) -> None:
        now = time.monotonic()
        if factor <= 0.0 or self._origin is None or self._origin[2] != factor:
            self._origin = (now, sim_time, factor)
            return
        wall_origin, sim_origin, _ = self._origin
        delay = wall_origin + (sim_time - sim_origin) / factor - now
        if delay > 0.0:
            time.sleep(delay)
        elif delay < -self.FALL_BEHIND:
            self._origin = (now, sim_time, factor)


class SimNode(Node):
    """Publishes odom, ground_truth, proximity, joint_states, world and /clock; takes cmd_vel and wheel_cmd."""

    def __init__(self) -> None:
        super().__init__('sim')
        self._declare_parameters()
        world_path = self.get_parameter('world').value
        world = load_world(world_path) if world_path else default_world()
        self._time_step = self.get_parameter('time_step').value
        self._rtf = self.get_parameter('real_time_factor').value
        self._paused = self.get_parameter('paused').value
        self._pause_at = self.get_parameter('pause_at').value
        self._sim = Simulation(
            world, RobotModel(), time_step=self._time_step, seed=self.get_parameter('seed').value,
            noise=self.get_parameter('noise').value, cmd_timeout=self.get_parameter('cmd_timeout').value)
        self._lock = threading.Lock()
        self._commanded = threading.Event()
        self._lockstep = self.get_parameter('lockstep').value
        self._lockstep_timeout = self.get_parameter('lockstep_timeout').value
        self._answered_once = False
        self._resends = 0
        self.failure = ''
        self._running = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim_loop', daemon=True)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        prefix = self.get_parameter('frame_prefix').value
        self._frames = {name: prefix + name for name in ('odom', 'base_link', 'world', *SENSOR_NAMES)}
        self._make_messages(world)
        self._make_interfaces()
        self.get_logger().info(
            f'sim ready: world {world_path or "default arena"}, time step {self._time_step} s, '
            f'real-time factor {self._rtf or "max"}, seed {self.get_parameter("seed").value}, '
            f'noise {"on" if self.get_parameter("noise").value else "off"}')

    def _declare_parameters(self) -> None:
        for name, (default, descriptor) in PARAMETERS.items():
            self.declare_parameter(name, default, descriptor)

    def _on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        with self._lock:
            for param in params:
                if param.name == 'real_time_factor':
                    self._rtf = param.value
                elif param.name == 'paused':
                    self._paused = param.value
                elif param.name == 'pause_at':
                    self._pause_at = param.value
                elif param.name == 'cmd_timeout':
                    self._sim.cmd_timeout = param.value
        return SetParametersResult(successful=True)

    def _make_messages(self, world: World) -> None:
        """Messages are built once and refilled every step: it halves the cost of publishing."""
        self._odom = Odometry()
        self._odom.header.frame_id = self._frames['odom']
        self._odom.child_frame_id = self._frames['base_link']
        self._odom.pose.covariance = _diagonal(POSE_COVARIANCE)
        self._odom.twist.covariance = _diagonal(TWIST_COVARIANCE)
        self._truth = Odometry()
        self._truth.header.frame_id = self._frames['world']
        self._truth.child_frame_id = self._frames['base_link']
        model = RobotModel()
        self._ranges = []
        for name in SENSOR_NAMES:
            msg = Range()
            msg.header.frame_id = self._frames[name]
            msg.radiation_type = Range.INFRARED
            msg.field_of_view = model.ir_aperture
            msg.min_range = 0.0
            msg.max_range = model.ir_range
            self._ranges.append(msg)
        self._joints = JointState()
        self._joints.name = JOINT_NAMES
        self._clock_msg = Clock()
        self._world_msg = String(data=yaml.safe_dump(world.to_dict(), sort_keys=False))

    def _make_interfaces(self) -> None:
        # Reliable KEEP_LAST: a reader gets a sample only while it is still in the publisher's history, so
        # the history holds about a second of steps at 10x real time; a recorder that stalls for a moment
        # (a disk flush, a garbage collection) then loses nothing.
        depth = PUBLISHER_HISTORY_STEPS
        self._pub_clock = self.create_publisher(Clock, '/clock', depth)
        self._pub_odom = self.create_publisher(Odometry, 'odom', depth)
        self._pub_truth = self.create_publisher(Odometry, 'ground_truth', depth)
        self._pub_range = self.create_publisher(Range, 'proximity', depth * len(SENSOR_NAMES))
        self._pub_joints = self.create_publisher(JointState, 'joint_states', depth)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.create_publisher(String, 'world', latched).publish(self._world_msg)
        self._pub_collisions = self.create_publisher(UInt32, 'collisions', latched)
        self._pub_collisions.publish(UInt32(data=0))
        if self.get_parameter('cmd_vel_stamped').value:
            self.create_subscription(TwistStamped, 'cmd_vel', lambda m: self._on_twist(m.twist), 10)
        else:
            self.create_subscription(Twist, 'cmd_vel', self._on_twist, 10)
        self.create_subscription(Float64MultiArray, 'wheel_cmd', self._on_wheel_cmd, 10)
        self.create_service(Empty, 'reset', self._on_reset)

    def _on_twist(self, msg: Twist) -> None:
        self._command('cmd_vel', self._sim.command_twist, msg.linear.x, msg.angular.z)

    def _on_wheel_cmd(self, msg: Float64MultiArray) -> None:
        if len(msg.data) != 2:
            self.get_logger().warning(
                f'wheel_cmd refused: data must be [left, right] rad/s, got {len(msg.data)} values',
                throttle_duration_sec=WARN_PERIOD)
            return
        self._command('wheel_cmd', self._sim.command_wheels, msg.data[0], msg.data[1])

    def _command(self, topic: str, apply: object, first: float, second: float) -> None:
        try:
            with self._lock:
                apply(first, second)
        except CommandError as error:
            self.get_logger().warning(f'{topic} refused: {error}', throttle_duration_sec=WARN_PERIOD)
            return
        self._commanded.set()

    def _on_reset(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        with self._lock:
            self._sim.reset()
        self.get_logger().info('reset: robot back at its start pose, odometry zeroed')
        return response

    def start(self) -> None:
        self._running.set()
        self._thread.start()

    def stop(self) -> None:
        self._running.clear()
        self._commanded.set()  # a lockstep loop waiting for a command wakes up and sees it must end
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)

    def _run(self) -> None:
        """The loop thread: a failure in it ends the node (exit code 1) instead of freezing time silently."""
        try:
            self._loop()
        except Exception as error:  # noqa: BLE001 - anything at all ends the node, with its story
            if self.context.ok():  # not merely the context going away under us while shutting down
                self.failure = f'simulation loop failed: {error!r}'
                self.get_logger().fatal(self.failure)
                self.context.try_shutdown()

    def _loop(self) -> None:
        """Step and publish until stopped, paced by the real-time factor; idle while paused."""
        pacer = Pacer()
        resend = False
        while self._running.is_set() and self.context.ok():
            if self._paused:
                pacer.restart()
                time.sleep(0.01)
                continue
            with self._lock:
                events = None if resend else self._sim.step()
                self._publish()
                rtf, now_sim = self._rtf, self._sim.time
            if events is not None:
                self._after_step(events, now_sim)
            resend = self._lockstep and not self._await_command()
            pacer.wait(now_sim, rtf)

    def _after_step(self, events: StepEvents, now_sim: float) -> None:
        if events.timed_out:
            self.get_logger().info(f'no command for {self._sim.cmd_timeout:g} s: wheels stopped (t={now_sim:.2f} s)')
        for robot in events.new_contacts:
            count = int(self._sim.collisions[robot])
            x, y, _ = self._sim.true_pose[robot]
            self._pub_collisions.publish(UInt32(data=count))
            self.get_logger().warning(f'collision #{count} at x={x:.3f} y={y:.3f} (t={now_sim:.2f} s)')
        if 0.0 < self._pause_at <= now_sim + 1e-9:
            self.set_parameters([Parameter('paused', value=True)])
            self.get_logger().info(f'paused at t={now_sim:.3f} s (pause_at)')

    def _await_command(self) -> bool:
        """Lockstep: wait for the controller to answer this step; False if the step should be sent again.

        Until the controller has answered once, a step nobody answered is sent again rather than passed: a
        controller still connecting may have missed it (DDS matching is not visible from outside), and
        two runs would then start a step apart. A few resends at most, so a lost first answer cannot hang
        the simulation."""
        answered = self._commanded.wait(self._lockstep_timeout)
        self._commanded.clear()
        if answered:
            self._answered_once = True
        if answered or self._answered_once or self._resends >= LOCKSTEP_START_RESENDS:
            return True
        self._resends += 1
        self.get_logger().info(f'lockstep: no answer to t={self._sim.time:.3f} s yet, sending it again')
        return False

    def _publish(self) -> None:
        """One step's messages; `/clock` goes last, so a node whose timer fires on that tick has its data."""
        sim = self._sim
        stamp = _stamp(sim.time)
        _fill_odometry(self._odom, stamp, sim.odom_pose[0], sim.odom_twist[0])
        self._pub_odom.publish(self._odom)
        _fill_odometry(self._truth, stamp, sim.true_pose[0], sim.true_twist[0])
        self._pub_truth.publish(self._truth)
        for msg, value in zip(self._ranges, sim.ir_range[0]):
            msg.header.stamp = stamp
            msg.range = float(value)
            self._pub_range.publish(msg)
        self._joints.header.stamp = stamp
        self._joints.position = [float(a) for a in sim.wheel_angles[0]]
        self._joints.velocity = [float(w) for w in sim.wheel_speeds[0]]
        self._pub_joints.publish(self._joints)
        self._clock_msg.clock = stamp
        self._pub_clock.publish(self._clock_msg)


def _stamp(seconds: float) -> Time:
    nanoseconds = round(seconds * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def _fill_odometry(msg: Odometry, stamp: object, pose: object, twist: object) -> None:
    x, y, yaw = (float(v) for v in pose)
    msg.header.stamp = stamp
    msg.pose.pose.position.x = x
    msg.pose.pose.position.y = y
    msg.pose.pose.orientation.z = math.sin(yaw / 2.0)
    msg.pose.pose.orientation.w = math.cos(yaw / 2.0)
    msg.twist.twist.linear.x = float(twist[0])
    msg.twist.twist.angular.z = float(twist[1])


def main(args: list[str] | None = None) -> None:
    # FastDDS sends from its own thread instead of inside publish(): the loop thread is then free to step
    # (measured with benchmarks/bench_sim_node.py: about 1.5x the real-time factor with a subscriber attached).
    os.environ.setdefault('RMW_FASTRTPS_PUBLICATION_MODE', 'ASYNCHRONOUS')
    rclpy.init(args=args)
    node = None
    try:
        node = SimNode()
        node.start()
        spin_until_shutdown(node)
    except (WorldError, ParameterException) as error:
        rclpy.logging.get_logger('sim').fatal(f'cannot start: {error}')
        raise SystemExit(2)
    finally:
        if node is not None:
            node.stop()
            node.destroy_node()
        rclpy.try_shutdown()
    if node is not None and node.failure:
        raise SystemExit(1)


if __name__ == '__main__':
    main()
