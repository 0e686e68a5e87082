"""`sim`: the e-puck simulator node — a thin ROS 2 shell around `epuck_ros.simulation.Simulation`.

The simulation steps in its own thread, paced by `real_time_factor` against the wall clock
(0 = as fast as the machine can go), and is the source of `/clock`; the executor thread receives
commands, service calls and parameters. One exception, for speed: in lockstep at `real_time_factor` 0 the
executor thread takes the next step itself when a step's last answer arrives (`SimNode._on_command`). Every
message of a step carries that step's simulated time, and `/clock` goes out last. Each robot's topics belong to
its `RobotPorts`.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable

import rclpy
import yaml
from rclpy.exceptions import ParameterException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String
from std_srvs.srv import Empty, Trigger
from visualization_msgs.msg import MarkerArray

from epuck_ros.conversions import stamp_from_seconds
from epuck_ros.markers import world_markers
from epuck_ros.model import TIME_STEP, RobotModel
from epuck_ros.nodes.ack_window import AckWindow, history_steps, window_steps
from epuck_ros.nodes.announcements import ANNOUNCEMENT_QOS, SIMULATORS_TOPIC, announcement, parse_announcement
from epuck_ros.nodes.dds_profile import use_package_profile, warn_if_not_fast_dds
from epuck_ros.nodes.params import ParamSpec, Usage, command_line_value, declare_parameters, prepare_arguments
from epuck_ros.nodes.qos import LATCHED
from epuck_ros.nodes.robot_ports import JOINT_NAMES, WARN_PERIOD, WORLD_FRAME, RobotPorts, quiet_publisher
from epuck_ros.nodes.sense_ports import SENSE_POLL, SENSE_TOPICS, SenseError, SensePorts
from epuck_ros.nodes.serialized import Patch
from epuck_ros.nodes.spinning import end_process, handle_shutdown_signals, shutdown_requested, spin_until_shutdown
from epuck_ros.nodes.tf_ports import TfPorts
from epuck_ros.simulation import CommandError, Simulation, StepEvents
from epuck_ros.world import WorldError, default_world, load_world, place_robots

__all__ = ['JOINT_NAMES', 'SIM_PARAMETERS', 'SimNode', 'main']

LOCKSTEP_START_RESENDS = 3
"""Times an unanswered first step is sent again (one `lockstep_timeout` each) before the simulation goes on."""
OWN_RATE_AFTER = 2
"""Steps in a row a controller that has answered before may leave unanswered until the timeout before lockstep
takes it for one that answers at its own rate (a timer), not every step: waiting a `lockstep_timeout` for each
step it skips made a 10 Hz controller run at 3 % of real time."""
OWN_RATE_WAIT = 0.01
"""Wall seconds a step waits at most for controllers that answer at their own rate: long enough for one that
answers this step's /clock tick (a round trip is well under a millisecond), short enough that the steps it skips
cost little."""
GRAPH_POLL = 0.05
"""Wall seconds between two looks at which robots have a controller while lockstep waits for answers."""
IDLE_POLL = 0.05
"""Wall seconds between two looks at the parameters while paused."""
PACING_SLICE = 0.02
"""Pacing sleeps at most this long at a time, then reads the real-time factor again: a change takes effect at once."""
DISCOVERY_WINDOW = 1.0
"""The default of `discovery_window`: wall seconds from the creation of the sim's node (its DDS participant is up)
during which it looks for another simulator (another `/clock` publisher, or a node with its name) before it steps
or publishes anything. Participants
announce themselves every 0.5 s (fastdds_profiles.xml), so one already running is discovered within about that
(measured: 0-0.56 s with the two cores busy). A simulator discovered later still is caught by the announcements on
SIMULATORS_TOPIC: the later of two refuses then, the earlier goes on. It was 1.5 s from the process start, when
announcements came every 3 s: the window was then most of the time to first motion (benchmarks/bench_startup.py)."""
ANNOUNCEMENT_WAIT = 3.0
"""Wall seconds a `/clock` publisher seen in the graph during the discovery window may go unexplained by a newer
simulator's announcement before this simulator refuses (a bag player, or an older simulator, never announces later)."""
WATCH_PERIOD = 2.0
"""Wall seconds between two looks for another `/clock` publisher once running."""
SUMMARY_PERIOD = 30.0
"""Wall seconds between two summaries of a repeated condition (command time-outs)."""

SIM_PARAMETERS = [
    ParamSpec('time_step', TIME_STEP, 'simulated seconds per step (Webots basicTimeStep is 32 ms)', (0.001, 1.0),
              read_only=True),
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second; 0 = as fast as possible', (0.0, 1e4)),
    ParamSpec('paused', False, 'while true, simulated time stands still (nothing is stepped or published); '
                               'the step service advances one step'),
    ParamSpec('pause_at', 0.0, 'simulated time (s) at which the simulation pauses by itself, exactly; 0 = never',
              (0.0, 1e9)),
    ParamSpec('lockstep', False, 'step only once every robot that has a controller (a publisher on its wheel_cmd or '
                                 'cmd_vel) has answered the last step, or after lockstep_timeout: runs are the same '
                                 'whatever the load of the machine', read_only=True),
    ParamSpec('lockstep_timeout', 1.0, 'wall seconds a lockstep simulation waits for the answers before stepping '
                                       'anyway', (0.001, 60.0), read_only=True),
    ParamSpec('discovery_window', DISCOVERY_WINDOW, 'wall seconds from the start during which the simulator looks for '
                                                    'another simulator on the ROS domain before its first step; '
                                                    'bringup, which has watched the domain since before it started '
                                                    'the simulator, passes 0', (0.0, 10.0), read_only=True),
    ParamSpec('world', '', 'path to a world YAML file; empty = the built-in 1 m x 1 m arena', read_only=True),
    ParamSpec('robots', 0, 'number of robots: 0 = those of the world; N = N robots epuck0.. placed clear of '
                           'everything, seeded by seed', (0, 100000), read_only=True),
    ParamSpec('seed', 0, 'seed of every random draw (noise, placement): same seed, same run', (0, 2**31 - 1),
              read_only=True),
    ParamSpec('noise', True, 'IR sensor noise (Webots lookup table, relative Gaussian) on or off', read_only=True),
    ParamSpec('cmd_timeout', 0.5, 'simulated seconds without a command before a robot stops; 0 = never',
              (0.0, 3600.0)),
    ParamSpec('cmd_vel_stamped', False, 'subscribe cmd_vel as geometry_msgs/TwistStamped instead of Twist',
              read_only=True),
    ParamSpec('frame_prefix', '', 'prefix of every frame_id (e.g. "sim1/"); with several robots each robot\'s '
                                  'frames are <prefix><name>/odom, ...', read_only=True),
    ParamSpec('senses', '', 'comma-separated senses every robot computes whether or not their topics have '
                            'subscribers: camera, ground, light, imu (a sense is computed anyway while its topic has '
                            'a subscriber)', read_only=True),
    ParamSpec('camera_width', 52, 'camera image width in pixels (the field of view stays 0.84 rad)', (1, 1024),
              read_only=True),
    ParamSpec('camera_height', 39, 'camera image height in pixels', (1, 1024), read_only=True),
]
"""The simulator's parameters; `bringup` routes `-p` assignments with this table."""

USAGE = Usage(
    'sim',
    'The e-puck simulator: steps the robots of a world and publishes, per robot, odom, ground_truth, proximity '
    '(8 Range), ir_raw (the 8 raw IR values), joint_states and collisions, and while they have subscribers '
    'camera/image_raw, camera/camera_info, ground_raw, light_raw and imu, plus the latched world and '
    'world_markers and /clock; takes cmd_vel (Twist) or wheel_cmd ([left, right] rad/s) per robot; services '
    'reset (Empty) and step (Trigger, one step while paused). With several robots, robot NAME\'s topics are '
    'NAME/odom, NAME/cmd_vel, ...',
    'sim --ros-args -p real_time_factor:=0 -p seed:=4 -p robots:=5')


class Pacer:
    """Sleeps so that simulated time runs `factor` times wall time (factor 0: no sleep at all).

    The sleep is cut into short slices and the factor read again after each, so a change of the factor takes
    effect within a slice, whatever the factor was (1e-300 included: nothing divides by it)."""

    FALL_BEHIND = 0.5
    """Wall seconds behind schedule after which pacing starts afresh instead of bursting to catch up."""

    def __init__(self) -> None:
        self._origin: tuple[float, float, float] | None = None  # wall time, sim time, factor

    def restart(self) -> None:
        self._origin = None

    def wait(self, sim_time: float, factor: Callable[[], float], keep_waiting: Callable[[], bool]) -> None:
        """Return once wall time has caught up with `sim_time` at the current `factor()`."""
        while keep_waiting():
            rate, now = factor(), time.monotonic()
            if rate <= 0.0 or self._origin is None or self._origin[2] != rate:
                self._origin = (now, sim_time, rate)  # a new rate paces from this step on
                return
            wall_origin, sim_origin, _ = self._origin
            ahead = (sim_time - sim_origin) - rate * (now - wall_origin)  # simulated seconds ahead of schedule
            if ahead <= 0.0:
                if -ahead > rate * self.FALL_BEHIND:
                    self._origin = (now, sim_time, rate)
                return
            time.sleep(PACING_SLICE if ahead >= rate * PACING_SLICE else ahead / rate)


class RepeatedCondition:
    """A condition that may happen thousands of times (a robot's command time-out): logged the first time for each
    robot, then counted, with a summary every `SUMMARY_PERIOD` wall seconds and at the end."""

    def __init__(self, log: Callable[[str], None], what: str) -> None:
        self._log, self._what = log, what
        self._counts: Counter[str] = Counter()
        self._unreported: Counter[str] = Counter()
        self._last_summary = time.monotonic()

    def happened(self, robot: str, first_message: str) -> None:
        if not self._counts[robot]:
            self._log(f'{first_message} (further ones are counted, not logged)')
        else:
            self._unreported[robot] += 1
        self._counts[robot] += 1
        if self._unreported and time.monotonic() - self._last_summary > SUMMARY_PERIOD:
            self.summarise()

    def summarise(self) -> None:
        if self._unreported:
            counts = ', '.join(f'{robot} {count}' for robot, count in sorted(self._unreported.items()))
            self._log(f'{self._what} {sum(self._unreported.values())} more times ({counts})')
        self._unreported.clear()
        self._last_summary = time.monotonic()


class SimNode(Node):
    """The simulator: one `RobotPorts` per robot, plus /clock, world, world_markers, reset and step."""

    def __init__(self, started: float | None = None) -> None:
        """`started`: monotonic time the process started (this simulator's place among others: who came first)."""
        super().__init__('sim')
        self._node_created = time.monotonic()
        """The discovery window counts from here."""
        self._started = self._node_created if started is None else started
        values = declare_parameters(self, SIM_PARAMETERS)
        self._stop_listening_to_own_clock()
        world = load_world(values['world']) if values['world'] else default_world()
        if values['robots'] > 0:
            world = place_robots(world, values['robots'], values['seed'])
        self._time_step = values['time_step']
        self._rtf = values['real_time_factor']
        self._paused = values['paused']
        self._pause_at = values['pause_at']
        self._lockstep = values['lockstep']
        self._lockstep_timeout = values['lockstep_timeout']
        self._discovery_window = values['discovery_window']
        self._sim = Simulation(world, RobotModel(), time_step=self._time_step, seed=values['seed'],
                               noise=values['noise'], cmd_timeout=values['cmd_timeout'])
        self._forced_senses = _senses(values['senses'])
        if (values['camera_width'], values['camera_height']) != self._sim.senses.camera_size:
            self._sim.senses.set_camera_size(values['camera_width'], values['camera_height'])
        for kind in self._forced_senses:
            self._sim.senses.want(kind, range(len(world.robots)))
        self._lock = threading.Lock()
        """Guards the simulation: the loop thread steps it (in lockstep the executor thread may too), the executor
        thread commands and resets it."""
        self._answers = threading.Condition()
        """Lockstep: guards the answers below; notified when the answers the loop waits for are in."""
        self._awaited: set[int] = set()
        """Lockstep: the robots whose answer to the current step is still awaited (empty: any answer)."""
        self._waiting_for: list[RobotPorts] = []
        """Lockstep: the robots whose answers the current step waits for (those driven, else all of them)."""
        self._any_answer = True
        """Lockstep: no robot has a controller: any command answers the step."""
        self._parked = False
        """Lockstep: the loop thread waits for the current step's answers; the executor thread may step itself
        (`_on_command`)."""
        self._answers_deadline = 0.0
        """Lockstep: monotonic time at which the loop stops waiting for the current step's answers."""
        self._next_watch = 0.0
        self._wake = threading.Event()
        self._step_requests = 0
        self._stepped = threading.Condition()
        self._resends = 0
        self.failure = ''
        self.refusal = ''
        """Why this simulator will not run (another one is there); main() exits 2 with it."""
        self._warned_newcomer = False
        self._newer_simulator_seen = False
        """A simulator that started after this one announced itself: it refuses, this one goes on."""
        self._running = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim_loop', daemon=True)
        self._timeouts = RepeatedCondition(self.get_logger().info, 'command time-out: wheels stopped')
        self._stalled_topics: set[str] = set()
        self.add_post_set_parameters_callback(self._on_parameters_set)

        history = history_steps(len(world.robots))
        stream = QoSProfile(depth=history, reliability=ReliabilityPolicy.RELIABLE)
        several = len(world.robots) > 1
        self.ports = []
        for index, name in enumerate(self._sim.names):
            if shutdown_requested():   # Ctrl-C while a swarm's ports are made (1,000 robots take ~15 s): stop now
                raise StartInterrupted()
            self.ports.append(RobotPorts(self, index, name, several, stream, LATCHED, self._on_command,
                                         values['frame_prefix'], values['cmd_vel_stamped']))
        self.sense_ports = [SensePorts(self, index, name, several, stream, self._sim, values['frame_prefix'])
                            for index, name in enumerate(self._sim.names)]
        self._sensing: list[SensePorts] = []
        self._sense_turn = 0
        """The robots with a subscriber on some sense topic: their sense messages are published after each step."""
        self.create_timer(SENSE_POLL, self._update_sense_wants)
        self._tf = TfPorts(self, self.ports, self._sim, several, stream, LATCHED, values['frame_prefix'] + WORLD_FRAME)
        quiet_publisher(self, String, 'world', LATCHED).publish(
            String(data=yaml.safe_dump(world.to_dict(), sort_keys=False)))
        quiet_publisher(self, MarkerArray, 'world_markers', LATCHED).publish(
            world_markers(world, values['frame_prefix'] + WORLD_FRAME))
        self.create_service(Empty, 'reset', self._on_reset)
        self.create_service(Trigger, 'step', self._on_step)
        self._clock_pub = quiet_publisher(self, Clock, '/clock', stream)
        started_ns = time.time_ns() - round((time.monotonic() - self._started) * 1e9)
        self._identity = announcement(started_ns, os.getpid())
        quiet_publisher(self, String, SIMULATORS_TOPIC, ANNOUNCEMENT_QOS).publish(String(data=self._identity.text()))
        self.create_subscription(String, SIMULATORS_TOPIC, self._on_simulator, ANNOUNCEMENT_QOS)
        self._clock_message = Patch(Clock(), [('clock.sec', 'i'), ('clock.nanosec', 'I')])
        self._acks = AckWindow(self._stream_publishers, window_steps(history), self._on_ack_stall, self._kept_all)
        shown = ', '.join(world.names[:5]) + (', ...' if len(world.names) > 5 else '')
        robots = f'{len(world.names)} robots ({shown})' if several else 'one robot'
        warn_if_not_fast_dds(self.get_logger())
        self.get_logger().info(
            f'sim ready: world {values["world"] or "default arena"}, {robots}, time step {self._time_step} s, '
            f'real-time factor {self._rtf or "max"}, seed {values["seed"]}, noise {"on" if values["noise"] else "off"}'
            f'{", lockstep" if self._lockstep else ""}{", paused" if self._paused else ""}')

    # --- start-up ---------------------------------------------------------------------------------------

    def _stop_listening_to_own_clock(self) -> None:
        """The clock source never follows `/clock` (it would hear itself, and pay for it): use_sim_time off."""
        if self.get_parameter('use_sim_time').value:
            self.set_parameters([Parameter('use_sim_time', value=False)])
            self.get_logger().info('use_sim_time ignored: the simulator is the source of /clock, it does not follow it')

    def _another_simulator(self) -> str:
        """What shows another simulator (another `/clock` publisher: a sim, a bag being played; or a node with this
        one's name), or ''."""
        clocks = self.get_publishers_info_by_topic('/clock')
        if len(clocks) > 1:  # ours is one
            who = ', '.join(sorted({f'{c.node_namespace.rstrip("/")}/{c.node_name}' for c in clocks
                                    if not c.node_name.startswith('_NODE_NAME_UNKNOWN')})) or 'another node'
            return f'/clock is published by {who}'
        if self.get_node_names_and_namespaces().count((self.get_name(), self.get_namespace())) > 1:
            return f'a node named {self.get_fully_qualified_name()} exists'
        return ''

    def _on_simulator(self, msg: String) -> None:
        """Another simulator's announcement: the one that started later refuses to run."""
        other = parse_announcement(msg.data)
        if other is None or other == self._identity or self.refusal:
            return
        who = f'pid {other.pid} on {other.host}'
        if other < self._identity:
            self.refusal = self._refusal(
                f'the simulator {who} started {(self._identity.started_ns - other.started_ns) * 1e-9:.1f} s earlier')
        else:
            self._newer_simulator_seen = True
            if not self._warned_newcomer:
                self._warned_newcomer = True
                self.get_logger().warning(f'another simulator appeared ({who}): it refuses to run')

    def _refusal(self, found: str) -> str:
        return (f'another simulator runs on ROS domain {os.environ.get("ROS_DOMAIN_ID", "0")}: {found}; '
                'stop it or use another ROS_DOMAIN_ID')

    def _alone_on_the_domain(self) -> bool:
        """Before the first step: look for another simulator until the discovery window ends; refuse if there is.

        Another `/clock` publisher in the graph may be a simulator that started after this one (under load this
        one's window can outlast a newcomer's start-up): that one refuses by the announcements. So the graph alone
        refuses only if no newer simulator's announcement explains it within ANNOUNCEMENT_WAIT."""
        seen_at = None
        while self._running.is_set():
            if self.refusal:
                return False
            now = time.monotonic()
            found = '' if self._newer_simulator_seen else self._another_simulator()
            if found:
                seen_at = now if seen_at is None else seen_at
                if now - seen_at >= ANNOUNCEMENT_WAIT:
                    self.refusal = self._refusal(found)
                    return False
            elif now >= self._node_created + self._discovery_window:
                return True
            time.sleep(0.05)
        return True

    def _watch_for_newcomers(self) -> None:
        found = self._another_simulator()
        if found and not self._warned_newcomer:
            self._warned_newcomer = True
            self.get_logger().warning(f'another clock source appeared ({found}): a simulator refuses to run, '
                                      'anything else mixes up simulated time')

    def _stream_publishers(self) -> list:
        return [self._clock_pub] + [pub for ports in self.ports for pub in ports.stream_publishers] + \
            self._tf.stream_publishers

    def _kept_all(self, topic: str) -> bool:
        """Some reader of `topic` keeps all its samples (KEEP_ALL history: a recorder)."""
        return any(info.qos_profile.history == HistoryPolicy.KEEP_ALL
                   for info in self.get_subscriptions_info_by_topic(topic))

    def _on_ack_stall(self, topic: str) -> None:
        if topic not in self._stalled_topics:
            self._stalled_topics.add(topic)
            self.get_logger().warning(
                f'a reader of {topic} acknowledged nothing for 10 s: no longer waiting for it (it may lose messages)')

    # --- parameters, commands, services -----------------------------------------------------------------

    def _on_parameters_set(self, params: list[Parameter]) -> None:
        """Apply parameters once they are set: their descriptors (ranges, types) already refused bad values, as in
        the anchors' set_parameters_callback demo (checks before, effects after)."""
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
        self._wake.set()

    def _on_command(self, robot: int, topic: str, kind: str, first: float, second: float) -> None:
        apply = self._sim.command_wheels if kind == 'wheels' else self._sim.command_twist
        try:
            with self._lock:
                apply(robot, first, second)
        except CommandError as error:
            self.get_logger().warning(f'{topic} refused: {error}', throttle_duration_sec=WARN_PERIOD)
            return
        with self._answers:
            self.ports[robot].answered = True
            self._awaited.discard(robot)
            if self._awaited:
                return
            if not self._steps_on_answers():
                self._answers.notify()
                return
            self._take_answers()
            self._answers_deadline = time.monotonic() + self._lockstep_timeout  # the loop thread, parked, waits on
        # The step's answers are in and nothing paces the loop: step here, in the executor thread that received the
        # last answer. Handing the step to the loop thread was one more thread wake-up per lockstep round trip:
        # 52-59x real time that way, 64-69x this way (benchmarks/bench_lockstep.py, alternating runs).
        self._advance()
        with self._answers:
            self._expect_answers()

    def _on_reset(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        with self._lock:
            self._sim.reset()
        self.get_logger().info('reset: every robot back at its start pose, odometry zeroed')
        return response

    def _on_step(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """One step while paused; answers once that step is published (its /clock included)."""
        if not self._paused:
            response.success, response.message = False, 'not paused: the simulation is running (set paused:=true)'
            return response
        with self._stepped:
            target = self._sim.steps + 1
            self._step_requests += 1
            self._wake.set()
            done = self._stepped.wait_for(lambda: self._sim.steps >= target or not self._running.is_set(),
                                          timeout=max(5.0, 2 * self._lockstep_timeout))
        response.success = done and self._running.is_set()
        response.message = f't={self._sim.time:.3f} s' if response.success else 'the step did not happen in time'
        return response

    # --- the loop ---------------------------------------------------------------------------------------

    def start(self) -> None:
        self._running.set()
        self._thread.start()

    def stop(self) -> None:
        self._running.clear()
        self._wake.set()
        with self._answers:  # a lockstep loop waiting for answers wakes up and sees it must end
            self._answers.notify_all()
        with self._stepped:
            self._stepped.notify_all()
        self._acks.close()
        if self._thread.is_alive():
            self._thread.join(timeout=5.0)
        self._timeouts.summarise()

    def _run(self) -> None:
        """The loop thread: a failure in it ends the node (exit code 1) instead of freezing time silently."""
        try:
            self._loop()
        except Exception as error:  # noqa: BLE001 - anything at all ends the node, with its story
            if self.context.ok() and self._running.is_set():  # not merely the context going away under us
                self.failure = f'simulation loop failed: {error!r}'
                self.get_logger().fatal(self.failure)
                self.context.try_shutdown()

    def _loop(self) -> None:
        """Step and publish until stopped, paced by the real-time factor; idle while paused."""
        if not self._alone_on_the_domain():
            return
        pacer = Pacer()
        resend = False
        self._next_watch = time.monotonic() + WATCH_PERIOD
        while self._running.is_set() and self.context.ok() and not self.refusal:
            if self._paused and not self._step_requests:
                pacer.restart()
                self._acks.restart(self._sim.steps)
                self._wake.wait(IDLE_POLL)
                self._wake.clear()
                continue
            self._advance(resend)
            resend = self._lockstep and not self._await_answers()
            self._acks.published(self._sim.steps)
            pacer.wait(self._sim.time, lambda: self._rtf, lambda: self._running.is_set() and not self._paused)

    def _advance(self, resend: bool = False) -> None:
        """One step (or the last one sent again), published: by the loop thread, or in lockstep by the executor
        thread that received the step's last answer (`_on_command`)."""
        if time.monotonic() > self._next_watch:
            self._watch_for_newcomers()
            self._next_watch = time.monotonic() + WATCH_PERIOD
        with self._answers:
            for ports in self.ports:
                ports.answered = False
        with self._lock:
            events = None if resend else self._sim.step()
            self._publish()
            now_sim = self._sim.time
        if events is not None:
            self._after_step(events, now_sim)
            if self._step_requests:
                with self._stepped:  # the step service answers now; lockstep needs the executor free
                    self._step_requests -= 1
                    self._stepped.notify_all()

    def _publish(self) -> None:
        """One step's messages, robot by robot; `/clock` goes last, so a node whose timer fires on that tick has
        its data."""
        stamp = stamp_from_seconds(self._sim.time)
        for ports in self.ports:
            ports.publish(self._sim, stamp)
        for senses in self._sensing:
            senses.publish(self._sim, stamp)
        self._tf.publish(self._sim, stamp)
        self._clock_pub.publish(self._clock_message.bytes(stamp))
        self._poll_sense_wants()

    def _update_sense_wants(self) -> None:
        """Senses follow their topics' subscribers (see sense_ports): every robot every SENSE_POLL wall seconds."""
        with self._lock:
            for ports in self.sense_ports:
                self._update_wants_of(ports)

    def _poll_sense_wants(self) -> None:
        """One robot a step too (under the lock), in turn: at real_time_factor 0 the wall-clock poll alone would
        leave a controller that just enabled a sense without readings for hundreds of steps."""
        self._sense_turn = (self._sense_turn + 1) % len(self.sense_ports)
        self._update_wants_of(self.sense_ports[self._sense_turn])

    def _update_wants_of(self, ports: SensePorts) -> None:
        was = ports.publishing
        ports.update_wants(lambda kind, robot, wanted: self._sim.senses.want(kind, [robot], wanted),
                           self._forced_senses)
        if ports.publishing != was:
            self._sensing = [ports for ports in self.sense_ports if ports.publishing]

    def _after_step(self, events: StepEvents, now_sim: float) -> None:
        names = self._sim.names
        for robot in events.timed_out:
            self._timeouts.happened(names[robot], f'{names[robot]}: no command for {self._sim.cmd_timeout:g} s: '
                                                  f'wheels stopped (t={now_sim:.2f} s)')
        for robot in events.new_contacts:
            count = int(self._sim.collisions[robot])
            x, y, _ = self._sim.true_pose[robot].tolist()
            self.ports[robot].publish_collisions(count)
            self.get_logger().warning(f'{names[robot]}: collision #{count} at x={x:.3f} y={y:.3f} (t={now_sim:.2f} s)')
        if 0.0 < self._pause_at <= now_sim + 1e-9:
            self.set_parameters([Parameter('paused', value=True)])
            self.get_logger().info(f'paused at t={now_sim:.3f} s (pause_at)')

    def _await_answers(self) -> bool:
        """Lockstep: wait until every robot with a controller answered this step; False to send the step again.

        A robot nobody drives holds nobody up; with no controller at all the sim waits for any command, up to
        `lockstep_timeout`. Until a robot's controller has answered once, a step it did not answer is sent
        again rather than passed: a controller still connecting may have missed it, and two runs would then
        start a step apart. A few resends at most, so a lost first answer cannot hang the simulation.
        The graph (who has a controller) is read once per step and every GRAPH_POLL while waiting, and the command
        callback wakes this thread only once the last awaited answer is in (not at every answer, re-reading the
        graph each time: with 50 robots, 50 wake-ups and 5,000 graph look-ups per step). Meanwhile the executor
        thread may take the steps over while their answers come in (`_steps_on_answers`): this thread then goes on
        waiting, for the answers of each new step."""
        with self._answers:
            self._expect_answers()
            self._parked = True
            while True:
                if (any if self._any_answer else all)(ports.answered for ports in self._waiting_for):
                    self._take_answers()
                    self._parked = False
                    return True
                own_rate_only = not self._any_answer and all(
                    ports.own_rate for ports in self._waiting_for if not ports.answered)
                remaining = (self._own_rate_deadline if own_rate_only else self._answers_deadline) - time.monotonic()
                if remaining <= 0.0 or not self._running.is_set():
                    self._parked = False
                    break
                if not self._answers.wait(min(remaining, GRAPH_POLL)):
                    self._read_graph()
            waiting_for = self._waiting_for
        if time.monotonic() < self._answers_deadline and self._running.is_set():
            return True   # only controllers at their own rate were missing: no resend, no count
        self._note_own_rate(waiting_for)
        never_answered = [ports for ports in waiting_for if not ports.answered_once]
        if not never_answered or self._resends >= LOCKSTEP_START_RESENDS or not self._running.is_set():
            return True
        self._resends += 1
        self.get_logger().info(f'lockstep: no answer to t={self._sim.time:.3f} s yet, sending it again')
        return False

    def _note_own_rate(self, waited_for: list[RobotPorts]) -> None:
        """After a step timed out: count it for each controller that answered before but not this step; past
        `OWN_RATE_AFTER` in a row, wait at most `OWN_RATE_WAIT` for it from then on, saying once why and what to do."""
        for ports in waited_for:
            if ports.answered or not ports.answered_once:
                ports.missed_in_a_row = 0 if ports.answered else ports.missed_in_a_row
                continue
            ports.missed_in_a_row += 1
            if ports.missed_in_a_row >= OWN_RATE_AFTER and not ports.own_rate:
                ports.own_rate = True
                pace = 'as fast as possible' if self._rtf == 0.0 else f'at real_time_factor {self._rtf:g}'
                self.get_logger().warning(
                    f'lockstep: the controller of {ports.name} answered {OWN_RATE_AFTER} steps in a row only after '
                    f'lockstep_timeout ({self._lockstep_timeout:g} s): it runs at its own rate (a timer?), not once '
                    f'per step; from now on each step waits at most {OWN_RATE_WAIT * 1000:g} ms for it (the run '
                    f'goes on {pace}, no longer the same to the bit). To keep lockstep, publish one command per step '
                    f'(on each /clock tick or ir_raw message).')

    def _expect_answers(self) -> None:
        """A step is out: wait for its answers from now on, up to `lockstep_timeout` (under `_answers`)."""
        self._answers_deadline = time.monotonic() + self._lockstep_timeout
        self._own_rate_deadline = time.monotonic() + OWN_RATE_WAIT
        self._read_graph()

    def _read_graph(self) -> None:
        """Which robots' answers the current step waits for: those with a controller (under `_answers`)."""
        driven = [ports for ports in self.ports if ports.has_controller()]
        self._any_answer = not driven
        self._waiting_for = driven or self.ports
        self._awaited = {ports.index for ports in driven if not ports.answered}

    def _take_answers(self) -> None:
        """The current step is answered: note who answered, and clear the answers, so that no thread takes them
        for the next step's (under `_answers`)."""
        for ports in self._waiting_for:
            ports.answered_once = ports.answered_once or ports.answered
            if ports.answered:
                ports.missed_in_a_row = 0
        for ports in self.ports:
            ports.answered = False

    def _steps_on_answers(self) -> bool:
        """Whether the executor thread takes the next step itself once the current one is answered (under
        `_answers`): only while the loop thread waits for these answers and would step at once after them (nothing
        to pace, no pause, no `step` request, no look at the readers' acknowledgements due)."""
        return (self._parked and self._rtf == 0.0 and not self._paused and not self._step_requests
                and self._running.is_set() and not self.refusal and not self._acks.due(self._sim.steps))


def publication_mode(argv: list[str]) -> str:
    """Fast DDS's publication mode for this process (read when the participant is made, before any parameter).

    Free-running, Fast DDS sends from its own thread instead of inside publish(): the loop thread is then free to
    step (benchmarks/bench_sim_node.py: 50 robots 1.5-1.9x real time against 0.7-1.1x synchronously). In
    lockstep nothing runs while the controllers answer, and that hand-off to another thread is one more wake-up
    per message on the round trip: synchronous, one robot ran 32-37x real time against 10-24x (alternating runs,
    a window of 250 steps); timed from the first step, 36.8x against 18.5x with the controller asynchronous too
    (median of 5 alternating runs). Only `-p lockstep:=...` on the command line (what `bringup` passes) is looked
    at; lockstep from a parameter file runs the same, asynchronously."""
    return 'SYNCHRONOUS' if command_line_value(argv, 'lockstep') is True else 'ASYNCHRONOUS'


def _senses(value: str) -> frozenset[str]:
    """The `senses` parameter's words; an unknown one is a SenseError naming it."""
    words = frozenset(word.strip() for word in value.split(',') if word.strip())
    unknown = sorted(words - set(SENSE_TOPICS))
    if unknown:
        raise SenseError(f'senses: unknown sense {unknown[0]!r} (senses: {", ".join(SENSE_TOPICS)})')
    return words


class StartInterrupted(Exception):
    """Ctrl-C or SIGTERM came while the node was still being built."""


DESTROY_UP_TO = 50
"""Robots up to which the node's entities are destroyed one by one at exit, as the anchors do; beyond, the process
ends without it (destroying 1,000 robots' 11,000 publishers and subscriptions took 14 s, and SIGTERM 29 s in all):
the other participants drop ours after the lease of the package's DDS profile (2 s)."""


def main(args: list[str] | None = None) -> None:
    started = time.monotonic()
    argv = prepare_arguments(args, SIM_PARAMETERS, USAGE)
    use_package_profile()
    os.environ.setdefault('RMW_FASTRTPS_PUBLICATION_MODE', publication_mode(argv))
    handle_shutdown_signals()  # from now on: a signal during start-up ends the node cleanly once it is built
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    code = 0
    try:
        node = SimNode(started)
        node.start()
        # rclpy's EventsExecutor dispatches from C++ instead of rebuilding a wait set in Python for every received
        # command: about a third less CPU per lockstep step (measured with a behaviour answering every step).
        spin_until_shutdown(node, until=lambda: bool(node.refusal), executor_type=EventsExecutor)
        if node.refusal:
            print(f'sim: cannot start: {node.refusal}', file=sys.stderr)
            code = 2
    except (WorldError, ParameterException, SenseError) as error:
        print(f'sim: cannot start: {error}', file=sys.stderr)
        code = 2
    except StartInterrupted:
        print('sim: stopped while starting', file=sys.stderr)
        end_process(0)
    finally:
        if node is not None:
            node.stop()
            if len(node.ports) > DESTROY_UP_TO:
                end_process(1 if node.failure else code)
            node.destroy_node()
        rclpy.try_shutdown()
    if node is not None and node.failure:
        code = 1
    if code:
        raise SystemExit(code)


if __name__ == '__main__':
    main()
