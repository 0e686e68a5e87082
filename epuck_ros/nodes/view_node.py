"""`view`: the live view of a run in the browser — the node between the simulator's topics and the page.

It follows the latched `world` topic (arena, obstacles, robot names: one robot uses the unprefixed topics,
several use `<name>/...`), keeps the newest ground truth, odometry, IR readings, wheel speeds and collision count
of the robots and the simulated time (the step's stamp), and serves them to the page (`epuck_ros.view.server`).
What it reads for that is `view.follow`'s: a swarm's every robot from one `swarm/observation` message per step, a
robot's own topics only for the robots a page shows in detail (or when there is no swarm topic). The page's
controls reach the simulator only through its own interfaces: its `paused` and `real_time_factor` parameters, its
`step` and `reset` services and each robot's `cmd_vel`.

The view must never slow the simulator down, which may step thousands of times a second. Every subscription is
best-effort with a history of one, and the node takes its messages `SPIN_RATE` times a second rather than as they
come: in between, each topic keeps only its newest sample, so the view handles a fixed number of messages a
second whatever the simulator's rate, and the simulator never waits for it. Each subscriber still costs the
simulator a send per step, so the view reads only while a page is open (`view.follow`).
"""
from __future__ import annotations

import errno
import math
import queue
import threading
import time
from concurrent.futures import Future as ResultFuture
from concurrent.futures import TimeoutError as ResultTimeout
from functools import partial

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterEvent, ParameterValue
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.signals import SignalHandlerOptions
from rclpy.parameter_client import AsyncParameterClient
from rclpy.publisher import Publisher
from rclpy.subscription import Subscription
from rclpy.task import Future
from sensor_msgs.msg import Image, JointState, Range
from std_msgs.msg import Float64MultiArray, Int32MultiArray, String, UInt32
from std_srvs.srv import Empty, Trigger

from epuck_ros.conversions import seconds_from_stamp, yaw_from_quaternion
from epuck_ros.description import JOINT_NAMES
from epuck_ros.exit_codes import EXIT_BAD_INPUT
from epuck_ros.loopback import is_loopback
from epuck_ros.model import SENSOR_NAMES
from epuck_ros.ros.dds_profile import use_package_profile
from epuck_ros.ros.params import ParamSpec, Usage, declare_parameters, prepare_arguments
from epuck_ros.ros.on_demand import TOPICS_ON_DEMAND_FROM
from epuck_ros.ros.qos import LATCHED, NEWEST_ONLY, newest
from epuck_ros.ros.spinning import handle_shutdown_signals, shutdown_requested
from epuck_ros.sensors.png import png_bytes
from epuck_ros.swarm_messages import OBSERVATION_FIELDS, OBSERVATION_TOPIC, SwarmReader
from epuck_ros.view.follow import CAMERA_TOPIC, DETAIL_TOPICS, SWARM, Topic, wanted_topics
from epuck_ros.view.server import Action, ActionError, ViewServer
from epuck_ros.view.state import ViewState, robot_topic
from epuck_ros.world import WorldError, world_from_yaml

SPIN_RATE = 30.0
"""Times a second the node takes its newest messages: the page's frame rate, a fixed cost per second."""
ACTION_TIMEOUT = 5.0
"""Wall seconds the page waits for the simulator to answer an action."""
GRAPH_LOOK = 0.5
"""Wall seconds between two looks at the graph for robots' own ground_truth publishers, while some have none."""
DETAIL_FIELDS = {'odom': 'odom', 'joint_states': 'wheel_speeds'}
"""The reading each of DETAIL_TOPICS gives."""
DRIVE_IDLE = 2.0
"""Wall seconds after the page's last drive command before its cmd_vel publisher is removed (so a lockstep
simulator does not wait for a driver that has gone)."""

PARAMETERS = (
    ParamSpec('host', '127.0.0.1', 'address to serve the page on; anything but loopback lets other machines '
              'pause, reset and drive the simulation', read_only=True),
    ParamSpec('port', 8765, 'TCP port of the page; 0 = any free port (the printed URL says which)', (0, 65535),
              read_only=True),
    ParamSpec('sim_node', 'sim', 'name of the simulator node whose parameters the page shows and sets',
              read_only=True),
)
USAGE = Usage(
    program='view',
    summary='Serves a live view of the simulation in the browser (no internet needed): arena, obstacles, every '
            'robot with its IR rays and trail, simulated time, the real-time factor reached, collisions, and for '
            'the selected robot its wheel speeds and odometry error. Buttons pause, step, reset and set the '
            'real-time factor; arrows/WASD drive the selected robot. Prints "view: URL" once serving.',
    example='view --ros-args -p port:=8080     # then open http://127.0.0.1:8080/')

SETTINGS = ('paused', 'real_time_factor')
"""The simulator's parameters the page shows (and sets)."""


class CannotServe(Exception):
    """The page cannot be served (address in use, unknown host)."""


class ViewNode(Node):
    """Subscribes to the simulator's topics for every robot of the world and serves the page."""

    def __init__(self) -> None:
        super().__init__('view')
        values = declare_parameters(self, PARAMETERS)
        self.state = ViewState()
        self._requests: queue.SimpleQueue[tuple[Action, ResultFuture]] = queue.SimpleQueue()
        self._reading: dict[Topic, Subscription] = {}
        self._drivers: dict[str, tuple[Publisher, float]] = {}
        self._robot_names: tuple[str, ...] = ()
        self._has_ir_raw: set[str] = set()
        self._published: set[str] = set()
        """The robots whose own ground_truth had a publisher in the graph (`_look_for_publishers`)."""
        self._graph_looked = 0.0
        self._swarm_reader = SwarmReader()
        self._readers = {   # a robot's topic: its type, what takes it, its QoS (only the newest of each is drawn)
            'ground_truth': (Odometry, self._on_truth, NEWEST_ONLY),
            'ir_raw': (Float64MultiArray, self._on_ir_raw, NEWEST_ONLY),
            # bags recorded before `ir_raw` existed have only the 8 Range messages (depth: one step's worth)
            'proximity': (Range, self._on_range, newest(len(SENSOR_NAMES))),
            'odom': (Odometry, self._on_odom, NEWEST_ONLY), 'joint_states': (JointState, self._on_joints, NEWEST_ONLY),
            # the camera of the robot shown in detail: the simulator renders it while this subscription lasts
            CAMERA_TOPIC: (Image, self._on_image, NEWEST_ONLY),
            'collisions': (UInt32, self._on_collisions, LATCHED), 'leds': (Int32MultiArray, self._on_leds, LATCHED)}

        sim_node = values['sim_node']
        namespace = self.get_namespace().rstrip('/')
        self._sim_full_name = sim_node if sim_node.startswith('/') else f'{namespace}/{sim_node}'
        self._sim_parameters = AsyncParameterClient(self, sim_node)
        self._sim_parameters.on_parameter_event(self._on_parameter_event)
        self._settings_read = False
        self._step = self.create_client(Trigger, 'step')
        self._reset = self.create_client(Empty, 'reset')

        host, port = values['host'], values['port']
        try:
            self.server = ViewServer(host, port, self.state, self.act)
        except OSError as error:
            busy = ' (another view?): take any free port with -p port:=0, or -p view.port:=0 through bringup; ' \
                'the view prints the address it got' if error.errno == errno.EADDRINUSE else ''
            raise CannotServe(f'cannot serve on {host}:{port}: {error.strerror or error}{busy}') from None
        self._server_thread = threading.Thread(target=self.server.serve_forever, name='view_http', daemon=True)
        self._server_thread.start()
        # Last: the graph shows this subscription only once the page is served (bringup's readiness of the view).
        self.create_subscription(String, 'world', self._on_world, LATCHED)
        if not is_loopback(host):
            self.get_logger().warning(
                f'serving on {host}: anyone who can reach this machine can pause, reset and drive the simulation')
        print(f'view: {self.server.url}', flush=True)

    # --- from the simulator ------------------------------------------------------------------------------------

    def _on_world(self, msg: String) -> None:
        try:
            world = world_from_yaml(msg.data, source='world topic')
        except WorldError as error:
            self.get_logger().error(f'cannot draw the world: {" ".join(str(error).split())}')
            return
        self.state.set_world(world)
        self._apply(set())  # the previous world's robots
        for publisher, _ in self._drivers.values():
            self.destroy_publisher(publisher)
        self._drivers, self._robot_names = {}, tuple(robot.name for robot in world.robots)
        self._has_ir_raw, self._published, self._graph_looked = set(), set(), 0.0
        shown = ', '.join(self._robot_names[:5]) + (f', ... ({len(world.robots)})' if len(world.robots) > 5 else '')
        self.get_logger().info(f'world: {world.arena_size[0]:g} m x {world.arena_size[1]:g} m, robots {shown}')

    def _follow(self) -> None:
        """Read what the pages draw, the cheapest way the simulator offers it (`view.follow`)."""
        several = len(self._robot_names) > 1
        swarm = several and self.count_publishers(OBSERVATION_TOPIC) > 0
        pages_open = self.server.pages_open()
        if pages_open and not swarm:
            self._look_for_publishers()
        detailed = self.server.watched() & set(self._robot_names)
        self.state.set_detailed(frozenset(detailed))
        self._apply(wanted_topics(self._robot_names, pages_open, detailed, swarm, self._published,
                                  self._has_ir_raw, len(self._robot_names) < TOPICS_ON_DEMAND_FROM))

    def _look_for_publishers(self) -> None:
        """The robots whose own ground truth has a publisher, looked for at most every GRAPH_LOOK while some are
        not: one look at the graph's topics, then a count of publishers only for those of ours it shows."""
        if len(self._published) == len(self._robot_names) or time.monotonic() - self._graph_looked < GRAPH_LOOK:
            return
        self._graph_looked = time.monotonic()
        topics = {self.resolve_topic_name(robot_topic(self._robot_names, robot, 'ground_truth')): robot
                  for robot in self._robot_names if robot not in self._published}
        for name, _ in self.get_topic_names_and_types():
            if name in topics and self.count_publishers(name):
                self._published.add(topics[name])

    def _apply(self, wanted: set[Topic]) -> None:
        """Subscribe to the `wanted` topics not read yet, drop those no longer wanted."""
        for key in set(self._reading) - wanted:
            self.destroy_subscription(self._reading.pop(key))
            robot, topic = key
            if topic in DETAIL_TOPICS:
                self.state.update(robot, **{DETAIL_FIELDS[topic]: None})   # no stale figures when shown again
        for key in wanted - set(self._reading):
            robot, topic = key
            if robot == SWARM:
                self._reading[key] = self.create_subscription(
                    Float64MultiArray, OBSERVATION_TOPIC, self._on_swarm, NEWEST_ONLY, raw=True)
                continue
            msg_type, callback, qos = self._readers[topic]
            self._reading[key] = self.create_subscription(
                msg_type, robot_topic(self._robot_names, robot, topic), partial(callback, robot), qos)

    def _on_swarm(self, data: bytes) -> None:
        step = self._swarm_reader.read(data)
        if step is not None and step.stamp is not None and step.fields == OBSERVATION_FIELDS:
            self.state.set_swarm(step, time.monotonic())

    def _on_truth(self, robot: str, msg: Odometry) -> None:
        stamp = _seconds(msg.header.stamp)
        self.state.update(robot, pose=_planar_pose(msg), stamp=stamp)
        if robot == self._robot_names[0]:
            # The simulated time shown is that of the first robot's pose: every message of a step carries the
            # step's time, and not taking /clock too spares the simulator one send per step.
            self.state.set_time(stamp, time.monotonic())

    def _on_odom(self, robot: str, msg: Odometry) -> None:
        self.state.update(robot, odom=_planar_pose(msg))

    def _on_joints(self, robot: str, msg: JointState) -> None:
        try:
            speeds = tuple(msg.velocity[list(msg.name).index(joint)] for joint in JOINT_NAMES)
        except (ValueError, IndexError):
            return
        self.state.update(robot, wheel_speeds=speeds)

    def _on_ir_raw(self, robot: str, msg: Float64MultiArray) -> None:
        if len(msg.data) != len(SENSOR_NAMES) or not all(math.isfinite(v) for v in msg.data):
            return
        self._has_ir_raw.add(robot)   # its proximity Ranges are no longer read (`view.follow`)
        self.state.set_ir_raw(robot, list(msg.data))

    def _on_range(self, robot: str, msg: Range) -> None:
        sensor = msg.header.frame_id.rsplit('/', 1)[-1]
        if robot not in self._has_ir_raw and sensor in SENSOR_NAMES:
            self.state.set_ir_range(robot, SENSOR_NAMES.index(sensor), msg.range)

    def _on_leds(self, robot: str, msg: Int32MultiArray) -> None:
        self.state.update(robot, leds=[int(v) for v in msg.data[:10]])

    def _on_image(self, robot: str, msg: Image) -> None:
        if msg.encoding != 'rgb8' or len(msg.data) != 3 * msg.width * msg.height or msg.step != 3 * msg.width:
            return
        pixels = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.width, 3)
        self.state.set_camera(robot, png_bytes(pixels), _seconds(msg.header.stamp))

    def _on_collisions(self, robot: str, msg: UInt32) -> None:
        self.state.update(robot, collisions=msg.data)

    def _on_parameter_event(self, msg: ParameterEvent) -> None:
        if msg.node == self._sim_full_name:
            self._apply_settings({p.name: p.value for p in msg.changed_parameters})

    def _apply_settings(self, values: dict[str, ParameterValue]) -> None:
        settings = {name: parameter_value_to_python(value) for name, value in values.items() if name in SETTINGS}
        if settings:
            self.state.set_settings(**settings)

    def _read_settings_once(self) -> None:
        """The simulator's `paused` and `real_time_factor` as they are now; later changes come as parameter events."""
        if self._settings_read or not self._sim_parameters.services_are_ready():
            return
        self._settings_read = True

        def done(future: Future) -> None:
            if future.result() is not None:
                self._apply_settings(dict(zip(SETTINGS, future.result().values)))
        self._sim_parameters.get_parameters(list(SETTINGS)).add_done_callback(done)

    # --- from the page ----------------------------------------------------------------------------------------

    def act(self, action: Action) -> dict:
        """Called by the server's threads: the action is carried out on the node's thread; its answer is waited for."""
        result: ResultFuture = ResultFuture()
        self._requests.put((action, result))
        try:
            return result.result(timeout=ACTION_TIMEOUT)
        except ResultTimeout:
            raise ActionError(f'{action.name}: the simulator did not answer within {ACTION_TIMEOUT:g} s') from None

    def run_requests(self) -> None:
        """Carry out the page's queued actions and follow what the pages watch (on the node's thread, as rclpy
        wants)."""
        self._read_settings_once()
        self._follow()
        while not self._requests.empty():
            action, result = self._requests.get()
            try:
                self._start_action(action, result)
            except ActionError as error:
                result.set_exception(error)
        now = time.monotonic()
        for robot, (publisher, last) in list(self._drivers.items()):
            if now - last > DRIVE_IDLE:
                self.destroy_publisher(publisher)
                del self._drivers[robot]

    def _start_action(self, action: Action, result: ResultFuture) -> None:
        args = action.args
        if action.name == 'drive':
            self._drive(args['robot'], args['linear'], args['angular'])
            result.set_result(args)
        elif action.name in ('pause', 'real_time_factor'):
            if not self._sim_parameters.services_are_ready():
                raise ActionError(f'no simulator node {self._sim_full_name!r} to set parameters on')
            param = (Parameter('paused', value=args['paused']) if action.name == 'pause'
                     else Parameter('real_time_factor', value=args['value']))
            self._sim_parameters.set_parameters([param]).add_done_callback(partial(_parameter_set, param, result))
        else:
            client, request = ((self._step, Trigger.Request()) if action.name == 'step'
                               else (self._reset, Empty.Request()))
            if not client.service_is_ready():
                raise ActionError(f'the simulator offers no {client.srv_name} service')
            client.call_async(request).add_done_callback(partial(_service_answered, action.name, result))

    def _drive(self, robot: str, linear: float, angular: float) -> None:
        if robot not in self._robot_names:
            raise ActionError(f'no robot {robot!r} (robots: {", ".join(self._robot_names) or "none yet"})')
        publisher = self._drivers[robot][0] if robot in self._drivers else self.create_publisher(
            Twist, robot_topic(self._robot_names, robot, 'cmd_vel'), 10)
        self._drivers[robot] = (publisher, time.monotonic())
        twist = Twist()
        twist.linear.x, twist.angular.z = linear, angular
        publisher.publish(twist)

    def close(self) -> None:
        self.server.close()


def _planar_pose(msg: Odometry) -> tuple[float, float, float]:
    pose = msg.pose.pose
    q = pose.orientation
    return pose.position.x, pose.position.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)


def _seconds(stamp: Time) -> float:
    return seconds_from_stamp(stamp.sec, stamp.nanosec)


def _parameter_set(param: Parameter, result: ResultFuture, future: Future) -> None:
    answer = future.result()
    if answer is None or not answer.results:
        result.set_exception(ActionError(f'setting {param.name} failed: no answer'))
    elif not answer.results[0].successful:
        result.set_exception(ActionError(f'{param.name} refused: {answer.results[0].reason}'))
    else:
        result.set_result({param.name: param.value})


def _service_answered(name: str, result: ResultFuture, future: Future) -> None:
    answer = future.result()
    if answer is None:
        result.set_exception(ActionError(f'{name}: no answer'))
    elif isinstance(answer, Trigger.Response) and not answer.success:
        result.set_exception(ActionError(f'{name} refused: {answer.message}'))
    else:
        result.set_result({name: True, 'message': getattr(answer, 'message', '')})


def spin_thinned(node: ViewNode) -> None:
    """Take the newest message of each topic SPIN_RATE times a second (see the module docstring), and the page's
    actions; ends on Ctrl-C or SIGTERM (`ros.spinning`: the signal raises a flag, the context stays alive until
    `main`'s finally; rclpy's own handler shut the context down under a spin_once, and the view once ended with a
    segmentation fault on Ctrl-C in a loaded suite run)."""
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    period = 1.0 / SPIN_RATE
    while node.context.ok() and not shutdown_requested():
        started = time.monotonic()
        # One wait finds every ready entity; each spin_once runs one of them. A spin that changed nothing means
        # the ready ones are done (a service answer or parameter event left over waits for the next round).
        most = sum(len(list(entities)) for entities in (node.subscriptions, node.clients, node.services,
                                                        node.timers, node.waitables))
        for _ in range(most):
            version = node.state.version
            try:
                executor.spin_once(timeout_sec=0.0)
            except Exception:   # noqa: BLE001 - rclpy's RCLError when Ctrl-C shut the context down meanwhile
                if node.context.ok():
                    raise
                return
            if node.state.version == version:
                break
        node.run_requests()
        time.sleep(max(0.0, period - (time.monotonic() - started)))


def main(args: list[str] | None = None) -> None:
    argv = prepare_arguments(args, PARAMETERS, USAGE)
    use_package_profile()
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    handle_shutdown_signals()
    node = None
    try:
        node = ViewNode()
        spin_thinned(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except (CannotServe, ParameterException) as error:
        rclpy.logging.get_logger('view').fatal(f'cannot start: {error}')
        raise SystemExit(EXIT_BAD_INPUT) from None
    finally:
        if node is not None:
            node.close()
            node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
