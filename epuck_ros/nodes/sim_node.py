"""`sim`: the e-puck simulator node — a thin ROS 2 shell around `epuck_ros.simulation.Simulation`.

Threads: the loop thread steps the simulation, paced by `real_time_factor` against the wall clock (0 = as fast as
the machine can go), and is the source of `/clock`; the executor thread receives commands, service calls and
parameters (the node is spun by rclpy's single-threaded EventsExecutor; its callbacks share the default, mutually
exclusive callback group, so under any executor they never run two at a time). Who steps: the loop thread, which
holds the claim of the node's `Lockstep` (epuck_ros/lockstep.py); in lockstep at `real_time_factor` 0, while it waits
for a step's answers, it lends the claim to the thread that receives the last answer, which takes the next step. Every
message of a step carries that step's simulated time, and `/clock` goes out last. Each robot's topics belong to its
`RobotPorts`.
"""
from __future__ import annotations

import os
import sys
import threading
import time
from collections.abc import Collection

import numpy as np
import rclpy
import yaml
from rcl_interfaces.msg import SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import HistoryPolicy, QoSProfile
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String
from std_srvs.srv import Empty, Trigger
from visualization_msgs.msg import MarkerArray

from epuck_ros.description import frame_prefix
from epuck_ros.conversions import nanoseconds_from_seconds, stamp_from_seconds
from epuck_ros.integrity import HELD, NOT_LOCKSTEP
from epuck_ros.lockstep import DECLARATION_TOPIC, Answer, Controller, Lockstep
from epuck_ros.markers import world_markers
from epuck_ros.model import TIME_STEP, RobotModel
from epuck_ros.ros.ack_window import AckWindow, history_steps, window_steps
from epuck_ros.ros.declaration import read_declarations
from epuck_ros.ros.dds_profile import use_no_local_profile, use_package_profile, warn_if_not_fast_dds
from epuck_ros.ros.domain_watch import DISCOVERY_WINDOW, DomainWatch
from epuck_ros.ros.interface_ports import InterfacePorts
from epuck_ros.ros.lockstep_report import LockstepReport
from epuck_ros.ros.on_demand import TOPICS_ON_DEMAND_FROM, OnDemand
from epuck_ros.pacing import Controls, Pacer, Settings
from epuck_ros.ros.params import ParamSpec, Usage, command_line_value, declare_parameters, prepare_arguments
from epuck_ros.ros.qos import LATCHED, clock_kept, step_stream
from epuck_ros.ros.repeated import RepeatedCondition
from epuck_ros.ros.robot_ports import (CONTROLLERS, JOINT_NAMES, MATCH_COLUMNS, READERS, WARN_PERIOD, WORLD_FRAME,
                                       RobotPorts, quiet_publisher)
from epuck_ros.ros.sense_ports import SENSE_POLL, SENSE_TOPICS, SenseError, SenseFeeds
from epuck_ros.ros.serialized import Patch, PatchCache
from epuck_ros.ros.spinning import end_process, handle_shutdown_signals, shutdown_requested, spin_until_shutdown
from epuck_ros.ros.swarm_ports import SwarmPorts
from epuck_ros.ros.tf_ports import TfPorts
from epuck_ros.simulation import MAX_SEED, CommandError, Simulation, StepEvents
from epuck_ros.world import World, WorldError, default_world, load_world, place_robots

__all__ = ['JOINT_NAMES', 'SIM_PARAMETERS', 'SimNode', 'main']

IDLE_POLL = 0.05
"""Wall seconds between two looks at the parameters while paused."""

SIM_PARAMETERS = [
    ParamSpec('time_step', TIME_STEP, 'simulated seconds per step (Webots basicTimeStep is 32 ms)', (0.001, 1.0),
              read_only=True),
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second; 0 = as fast as possible', (0.0, 1e4)),
    ParamSpec('paused', False, 'while true, simulated time stands still (nothing is stepped or published); '
                               'the step service advances one step'),
    ParamSpec('pause_at', 0.0, 'simulated time (s) at which the simulation pauses by itself, exactly; 0 = never',
              (0.0, 1e9)),
    ParamSpec('lockstep', False, 'step only once every robot that has a controller (a publisher on its wheel_cmd or '
                                 'cmd_vel) has answered the last step, by name (a stamped answer): runs are the same '
                                 'whatever the load of the machine (lockstep_status says whether one was)',
              read_only=True),
    ParamSpec('lockstep_timeout', 0.0, 'wall seconds a lockstep step waits for the answers of the controllers in '
                                       'lockstep before it goes on without them (the run is then no longer '
                                       'reproducible); 0 = as long as it takes', (0.0, 3600.0), read_only=True),
    ParamSpec('lockstep_controllers', 1, 'in lockstep, the first step waits until this many robots have a connected '
                                         'controller (0 = no wait; by default a lockstep simulation waits for one): '
                                         'whoever starts the controllers saw them before the simulator may have; '
                                         'bringup and the epuck_sim fixture set it as they resume', (0, 100000)),
    ParamSpec('discovery_window', DISCOVERY_WINDOW, 'wall seconds from the start during which the simulator looks for '
                                                    'another simulator on the ROS domain before its first step; '
                                                    'bringup, which has watched the domain since before it started '
                                                    'the simulator, passes 0', (0.0, 10.0), read_only=True),
    ParamSpec('world', '', 'path to a world YAML file; empty = the built-in 1 m x 1 m arena', read_only=True),
    ParamSpec('robots', 0, 'number of robots: 0 = those of the world; N = N robots epuck0.. placed clear of '
                           'everything, seeded by seed', (0, 100000), read_only=True),
    ParamSpec('seed', 0, 'seed of every random draw (noise, placement): same seed, same run', (0, MAX_SEED),
              read_only=True),
    ParamSpec('noise', True, 'IR sensor noise (Webots lookup table, relative Gaussian) on or off', read_only=True),
    ParamSpec('cmd_timeout', 0.5, 'simulated seconds without a command before a robot stops; 0 = never',
              (0.0, 3600.0)),
    ParamSpec('cmd_vel_stamped', False, 'subscribe cmd_vel as geometry_msgs/TwistStamped instead of Twist',
              read_only=True),
    ParamSpec('frame_prefix', '', 'prefix of every frame_id (e.g. "sim1/"); with several robots each robot\'s '
                                  'frames are <prefix><name>/odom, ...', read_only=True),
    ParamSpec('senses', '', 'comma-separated senses every robot computes whether or not their topics have '
                            'subscribers: camera, ground, light, imu, tof (a sense is computed anyway while its topic '
                            'has a subscriber)', read_only=True),
    ParamSpec('camera_width', 52, 'camera image width in pixels (the field of view stays 0.84 rad)', (1, 1024),
              read_only=True),
    ParamSpec('camera_height', 39, 'camera image height in pixels', (1, 1024), read_only=True),
]
"""The simulator's parameters; `bringup` routes `-p` assignments with this table."""

USAGE = Usage(
    'sim',
    'The e-puck simulator: steps the robots of a world and publishes, per robot, odom, ground_truth, proximity '
    '(8 Range), ir_raw (the 8 raw IR values), joint_states and collisions, the latched robot_description, and '
    'while they have subscribers camera/image_raw, camera/camera_info, ground_raw, light_raw, imu and tof, plus the '
    'latched world, world_markers and /tf_static, and /tf and /clock; the e-puck\'s own interface while read '
    '(ps0..ps7, scan, ls0..ls7, image_raw, camera_info; led0..led9 taken); takes cmd_vel (Twist) or wheel_cmd '
    '([left, right] rad/s) per robot; services '
    'reset (Empty) and step (Trigger, one step while paused). With several robots, robot NAME\'s topics are '
    'NAME/odom, NAME/cmd_vel, ...',
    'sim --ros-args -p real_time_factor:=0 -p seed:=4 -p robots:=5')


class SimNode(Node):
    """The simulator: one `RobotPorts` per robot, plus /clock, world, world_markers, reset and step."""

    def __init__(self, started: float | None = None) -> None:
        """`started`: monotonic time the process started (this simulator's place among others: who came first)."""
        super().__init__('sim')
        created = time.monotonic()
        values = declare_parameters(self, SIM_PARAMETERS)
        values['frame_prefix'] = _frame_prefix(values['frame_prefix'])
        self._stop_listening_to_own_clock()
        world = _world(values)
        self._sim = self._make_simulation(world, values)
        self._lock = threading.Lock()
        """Guards the simulation: the stepping thread steps it, the executor thread commands and resets it."""
        self._controls = Controls(Settings(values['real_time_factor'], values['paused'], values['pause_at']))
        self._lockstep_on, self._lockstep_timeout = values['lockstep'], values['lockstep_timeout']
        self._running = threading.Event()
        self._thread = threading.Thread(target=self._run, name='sim_loop', daemon=True)
        self.failure = ''
        """Why the loop failed; main() exits 1 with it."""
        self._timeouts = RepeatedCondition(self.get_logger().info, 'command time-out: wheels stopped')
        self._stalled_topics: set[str] = set()
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        history = history_steps(len(world.robots))
        stream = step_stream(history)
        self._demand = OnDemand() if len(world.robots) >= TOPICS_ON_DEMAND_FROM else None
        """A swarm's per-robot topics waiting for their first reader or writer (`on_demand`)."""
        self.ports = self._make_ports(values, stream)
        self._swarm = SwarmPorts(self, self._sim.names, stream, self._on_swarm_command, self._on_declare) \
            if len(self.ports) > 1 else None
        self._senses = SenseFeeds(self, self._sim, stream, values['frame_prefix'], self._forced_senses, _stop_if_asked,
                                  companions=(InterfacePorts,))   # the e-puck's own interface (issue 32)
        self.create_timer(SENSE_POLL, self._update_sense_wants)
        _stop_if_asked()
        self._tf = TfPorts(self, self.ports, self._sim, len(self.ports) > 1, stream, LATCHED,
                           values['frame_prefix'] + WORLD_FRAME, demand=self._demand)
        publish_world(self, world, values['frame_prefix'])
        self.create_service(Empty, 'reset', self._on_reset)
        self.create_service(Trigger, 'step', self._on_step)
        self._clock_pub = quiet_publisher(self, Clock, '/clock', clock_kept(history))   # a late monitor: last ticks
        self._domain = DomainWatch(self, created, created if started is None else started, values['discovery_window'])
        self._clock_message = Patch(Clock(), [('clock.sec', 'i'), ('clock.nanosec', 'I')])
        self._acks = AckWindow(self._stream_publishers, window_steps(history), self._on_ack_stall, self._kept_all)
        self._report = LockstepReport(self, self._sim.names, HELD if self._lockstep_on else NOT_LOCKSTEP,
                                      self._lockstep_timeout, lambda: self._sim.time)
        self._declared: dict[int, Controller] = {}
        """What each robot's controller declared (`_on_declaration`)."""
        self._robot_of_topic = {topic: ports.index for ports in self.ports for topic in ports.command_topics}
        self._lockstep = self._make_lockstep(values['lockstep_controllers'])
        warn_if_not_fast_dds(self.get_logger())
        self._ready = self._ready_line(world, values)
        """Said once no other simulator was found before the first step (a second sim said it, then refused)."""

    def _make_simulation(self, world: World, values: dict) -> Simulation:
        """The core for `world`, with the senses the `senses` parameter asks for always computed."""
        sim = Simulation(world, RobotModel(), time_step=values['time_step'], seed=values['seed'],
                         noise=values['noise'], cmd_timeout=values['cmd_timeout'])
        self._forced_senses = _senses(values['senses'])
        if (values['camera_width'], values['camera_height']) != sim.senses.camera_size:
            sim.senses.set_camera_size(values['camera_width'], values['camera_height'])
        for kind in self._forced_senses:
            sim.senses.want(kind, range(len(world.robots)))
        return sim

    def _make_lockstep(self, controllers: int) -> Lockstep:
        """The step protocol's pairing, reporting through `_report`; in lockstep, the controllers' declarations
        read; `controllers`: how many to wait for before the first step (`lockstep_controllers`)."""
        report = self._report
        lockstep = Lockstep(len(self.ports), self._take_step, self._lockstep_timeout, driven=self._driven,
                            lend=self._lend_on_answers, on_stall=report.stall, on_resend=report.resend,
                            on_free=report.free, on_timeout=report.timeout, controller=self._controller,
                            on_leave=self._on_leave)
        if self._lockstep_on:
            read_declarations(self, self._on_declaration, self._on_bad_declaration)
        lockstep.require_controllers(controllers)
        return lockstep

    @property
    def refusal(self) -> str:
        """Why this simulator will not run (another one is there); main() exits 2 with it."""
        return self._domain.refusal

    # --- start-up ---------------------------------------------------------------------------------------

    def _stop_listening_to_own_clock(self) -> None:
        """The clock source never follows `/clock` (it would hear itself, and pay for it): use_sim_time off."""
        if self.get_parameter('use_sim_time').value:
            self.set_parameters([Parameter('use_sim_time', value=False)])
            self.get_logger().info('use_sim_time ignored: the simulator is the source of /clock, it does not follow it')

    def _make_ports(self, values: dict, stream: QoSProfile) -> list[RobotPorts]:
        several = len(self._sim.names) > 1
        ports = []
        patches = PatchCache()
        self._matches = np.zeros((len(self._sim.names), MATCH_COLUMNS), dtype=np.int64)
        """Every robot's matched readers and controllers (`robot_ports.Matched`), read for all robots at once."""
        for index, name in enumerate(self._sim.names):
            _stop_if_asked()
            ports.append(RobotPorts(self, index, name, several, stream, LATCHED, self._on_command,
                                    values['frame_prefix'], values['cmd_vel_stamped'], patches=patches,
                                    matches=self._matches[index], demand=self._demand))
        return ports

    @staticmethod
    def _ready_line(world: World, values: dict) -> str:
        shown = ', '.join(world.names[:5]) + (', ...' if len(world.names) > 5 else '')
        robots = f'{len(world.names)} robots ({shown})' if len(world.names) > 1 else 'one robot'
        return (
            f'sim ready: world {values["world"] or "default arena"}, {robots}, time step {values["time_step"]} s, '
            f'real-time factor {values["real_time_factor"] or "max"}, seed {values["seed"]}, '
            f'noise {"on" if values["noise"] else "off"}'
            f'{", lockstep" if values["lockstep"] else ""}{", paused" if values["paused"] else ""}')

    def _stream_publishers(self) -> list:
        return [self._clock_pub] + [pub for ports in self.ports for pub in ports.stream_publishers] + \
            self._tf.stream_publishers + (self._swarm.stream_publishers if self._swarm is not None else [])

    def _kept_all(self, topic: str) -> bool:
        """Some reader of `topic` keeps all its samples (KEEP_ALL history: a recorder)."""
        return any(info.qos_profile.history == HistoryPolicy.KEEP_ALL
                   for info in self.get_subscriptions_info_by_topic(topic))

    def _on_ack_stall(self, topic: str) -> None:
        if topic not in self._stalled_topics:
            self._stalled_topics.add(topic)
            self.get_logger().warning(
                f'a reader of {topic} acknowledged nothing for 10 s: no longer waiting for it (it may lose messages)')

    # --- parameters, commands, services (the executor thread) -------------------------------------------

    def _check_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validation only (their descriptors check types and ranges); `_apply_parameters` acts once they are set."""
        for param in params:
            if param.name == 'use_sim_time' and param.value:
                return SetParametersResult(successful=False, reason='the simulator is the source of /clock: it does '
                                                                    'not follow it (use_sim_time stays false)')
        return SetParametersResult(successful=True)

    def _apply_parameters(self, params: list[Parameter]) -> None:
        """The run-time parameters, once set: the loop sees them at once (also called by the stepping thread when it
        pauses at `pause_at`)."""
        changes = {param.name: param.value for param in params
                   if param.name in ('real_time_factor', 'paused', 'pause_at')}
        if changes:
            self._controls.update(**changes)
        for param in params:
            if param.name == 'cmd_timeout':
                with self._lock:
                    self._sim.cmd_timeout = param.value
            elif param.name == 'lockstep_controllers':
                self._lockstep.require_controllers(param.value)

    def _on_command(self, robot: int, topic: str, kind: str, first: float, second: float, named: int | None) -> None:
        """A command; in lockstep, paired with the current step by the step it names (`Lockstep.classify`): a repeat
        of an answer is dropped, as is one naming a step not reached yet, and a second, different answer to a step
        (it breaks the run). A command the simulation refuses (NaN) answers nothing."""
        apply = self._sim.command_wheels if kind == 'wheels' else self._sim.command_twist
        command = (topic, first, second)
        refused = ''
        applied = False
        with self._lock:   # the step cannot change between the verdict and the command (a step holds the lock)
            current = nanoseconds_from_seconds(self._sim.time)
            verdict = self._lockstep.classify(robot, named, current, command) if self._lockstep_on else None
            if verdict is Answer.FUTURE:
                refused = f'it names t={named * 1e-9:.3f} s, which the simulation has not reached (t=' \
                          f'{self._sim.time:.3f} s): is the controller\'s use_sim_time off?'
            elif verdict not in (Answer.REPEATED, Answer.CONFLICT):
                try:
                    apply(robot, first, second)
                    applied = True
                except CommandError as error:   # no answer: the robot keeps its last command, the step waits on
                    refused = str(error)
        if refused:
            self.get_logger().warning(f'{topic} refused: {refused}', throttle_duration_sec=WARN_PERIOD)
        if verdict is Answer.CONFLICT:
            self._report_conflict(robot, named, command)
        elif not applied or verdict is None:
            return
        elif verdict is Answer.BESIDE:
            if not self._controls.settings.paused:   # paused, it drives nothing before whoever resumes
                self._report.beside(robot, topic)
        else:
            # The step's last answer may take the next step here, in this thread (`_lend_on_answers`): handing the
            # step to the loop thread was one more thread wake-up per lockstep round trip.
            self._lockstep.answer(robot, verdict, named, command)

    def _report_conflict(self, robot: int, named: int, command: tuple[str, float, float]) -> None:
        if not self._report.integrity.reproducible:
            return   # said already (the first reason stays): no look at the graph for each of an intruder's answers
        last_named, last_command = self._lockstep.last_answer(robot)
        said = f'[{command[1]!r}, {command[2]!r}] on {command[0]}'
        if last_named == named and last_command is not None:
            topic, first, second = last_command
            detail = f'[{first!r}, {second!r}] on {topic}, then {said}'
        elif last_named == named:
            detail = f'an answer, then {said}'
        else:
            detail = f'{said}, after an answer to t={last_named * 1e-9:.3f} s'
        self._report.conflict(robot, named * 1e-9, detail, self.ports[robot].publishers())

    def _on_declaration(self, controller: Controller, topics: list[str]) -> None:
        """A controller's declaration (ros/declaration.py): what lockstep expects of it before its first answer.
        Topics of other simulators' robots are not ours to read."""
        for topic in topics:
            robot = self._robot_of_topic.get(topic)
            if robot is not None:
                self._declared[robot] = controller

    def _on_leave(self, robot: int) -> None:
        """Its controller left, saying goodbye: the goodbye is spent (a later controller of it declares anew)."""
        self._declared.pop(robot, None)
        self._report.leave(robot)

    def _on_bad_declaration(self, why: str) -> None:
        self.get_logger().warning(f'a declaration on {DECLARATION_TOPIC} refused: {why}',
                                  throttle_duration_sec=WARN_PERIOD)

    def _on_swarm_command(self, robots: np.ndarray, speeds: np.ndarray, named: int | None) -> None:
        """A swarm controller's answers (`SwarmPorts`): `_on_command`'s rule for each robot. When they answer the
        current step for every robot (a lockstep run's every step) it is one NumPy look at them all
        (`Lockstep.answers_step`), the speeds are set in one NumPy operation (`Simulation.command_all_wheels`, the same
        numbers as robot by robot) and the answers are noted at once (`Lockstep.answer_all`); anything else (some
        robots, a repeat, an unstamped stop, a refused number) robot by robot, where a whole answer sent again is a
        repeat (each robot's command is the one `answer_all` noted) and a different one a conflict."""
        topic = self._swarm.topic
        if self._lockstep_on and named is not None and len(robots) == len(self.ports):
            with self._lock:   # the step cannot change between the verdicts and the commands
                answered = self._lockstep.answers_step(robots, named, nanoseconds_from_seconds(self._sim.time))
                if answered:
                    everyone = np.empty_like(speeds)
                    everyone[robots] = speeds
                    try:
                        self._sim.command_all_wheels(everyone)
                    except CommandError:   # each robot's own verdict below
                        answered = False
            if answered:   # each robot's command as `_on_command` names it, if ever compared (a repeat, a conflict)
                self._lockstep.answer_all(robots, named, lambda robot: (topic, *everyone[robot].tolist()))
                return
        for robot, (left, right) in zip(robots.tolist(), speeds.tolist()):
            self._on_command(robot, topic, 'wheels', left, right, named)

    def _on_declare(self, robots: list[int]) -> None:
        """A swarm controller answers these robots' steps by name (`SwarmPorts`): declared in lockstep, as a
        declaration on DECLARATION_TOPIC says of a robot's own controller, it is waited for however long its first
        answer takes."""
        for robot in robots:
            self._declared[robot] = Controller.LOCKSTEP

    def _on_reset(self, request: Empty.Request, response: Empty.Response) -> Empty.Response:
        with self._lock:
            self._sim.reset()
            if not self._controls.settings.paused:
                self._report.broken('reset while running, at no particular step (pause first: paused:=true)')
        self.get_logger().info('reset: every robot back at its start pose, odometry zeroed')
        return response

    def _on_step(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        """One step while paused; answers once that step is published (its /clock included)."""
        if not self._controls.settings.paused:
            response.success, response.message = False, 'not paused: the simulation is running (set paused:=true)'
            return response
        target = self._sim.steps + 1
        response.success = self._controls.request_step(
            lambda: self._sim.steps >= target or not self._running.is_set(),
            timeout=max(5.0, 2 * self._lockstep_timeout)) and self._running.is_set()
        response.message = f't={self._sim.time:.3f} s' if response.success else 'the step did not happen in time'
        return response

    # --- the loop ---------------------------------------------------------------------------------------

    def start(self) -> None:
        self._running.set()
        self._thread.start()

    def stop(self) -> None:
        self._running.clear()
        self._controls.close()
        self._lockstep.close()   # a loop waiting for answers wakes up and sees it must end
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
        if not self._domain.alone(self._running.is_set) or not self._running.is_set():
            return
        self.get_logger().info(self._ready)
        self._lockstep.claim()   # from now on this thread steps (and lends the claim, see `_lend_on_answers`)
        pacer = Pacer()
        resend = False
        while self._running.is_set() and self.context.ok() and not self.refusal:
            if self._controls.idle():
                pacer.restart()
                self._acks.restart(self._sim.steps)
                self._controls.wait_while_idle(IDLE_POLL)
                continue
            if self._lockstep_on and not self._lockstep.await_controllers(self._stepping, self._report.controllers):
                continue
            if not self._sim.steps:
                self._acks.await_readers(self.count_subscribers, self._stepping)
            if resend or not self._sim.steps:   # each reader matched by now gets this step (`robot_ports.Matched`)
                for ports in self.ports:
                    ports.read_matches()
            self._lockstep.step(resend)
            resend = self._lockstep_on and not self._lockstep.await_answers()
            self._acks.published(self._sim.steps)
            pacer.wait(self._sim.time, lambda: self._controls.settings.real_time_factor,
                       lambda: self._running.is_set() and not self._controls.settings.paused)

    def _lend_on_answers(self) -> bool:
        """Whether the thread of a step's last answer takes the next step (the loop thread waits for these
        answers, `Lockstep.answer`): only when the loop thread would step at once after them (nothing to pace, no
        pause, no `step` request, no look at the readers' acknowledgements due)."""
        settings = self._controls.settings
        return (settings.real_time_factor == 0.0 and not settings.paused and not self._controls.steps_requested()
                and self._running.is_set() and not self.refusal and not self._acks.due(self._sim.steps))

    def _take_step(self, resend: bool) -> None:
        """One step (or the last one sent again), published; called by `Lockstep.step`, in the thread that holds
        its claim."""
        with self._lock:
            events = None if resend else self._sim.step()
            self._publish()
            now_sim = self._sim.time
        if events is not None:
            self._after_step(events, now_sim)
            self._controls.stepped()   # the step service answers now; lockstep needs the executor free

    def _publish(self) -> None:
        """One step's messages, robot by robot; `/clock` goes last, so a node whose timer fires on that tick has
        its data."""
        stamp = stamp_from_seconds(self._sim.time)
        for robot in np.flatnonzero(self._matches[:, READERS].any(axis=1)).tolist():   # robots someone reads
            self.ports[robot].publish(self._sim, stamp)
        if self._swarm is not None:
            self._swarm.publish(self._sim, stamp)
        self._senses.publish(stamp)
        self._tf.publish(self._sim, stamp)
        self._clock_pub.publish(self._clock_message.bytes(stamp))
        self._senses.update_next()

    def _update_sense_wants(self) -> None:
        """Senses follow their topics' subscribers (see sense_ports): every robot every SENSE_POLL wall seconds. A
        swarm's topics on demand (`on_demand`): one look at the graph's topics, outside the lock; those that got a
        reader or a writer are made under it (the loop thread publishes what is matched)."""
        made = []
        if self._demand is not None:
            graph = [topic for topic, _ in self.get_topic_names_and_types()]
            self._senses.offer_read_topics(graph)
            made = self._demand.due(graph, self.count_subscribers, self.count_publishers)
        with self._lock:
            for make in made:
                make()
            self._senses.update_all()

    def _after_step(self, events: StepEvents, now_sim: float) -> None:
        names = self._sim.names if events.timed_out or events.new_contacts else ()   # a tuple made anew each call
        for robot in events.timed_out:
            self._timeouts.happened(names[robot], f'{names[robot]}: no command for {self._sim.cmd_timeout:g} s: '
                                                  f'wheels stopped (t={now_sim:.2f} s)')
        for robot in events.new_contacts:
            count = int(self._sim.collisions[robot])
            x, y, _ = self._sim.true_pose[robot].tolist()
            self.ports[robot].publish_collisions(count)
            self.get_logger().warning(f'{names[robot]}: collision #{count} at x={x:.3f} y={y:.3f} (t={now_sim:.2f} s)')
        if 0.0 < self._controls.settings.pause_at <= now_sim + 1e-9:
            self.set_parameters([Parameter('paused', value=True)])
            self.get_logger().info(f'paused at t={now_sim:.3f} s (pause_at)')

    # --- lockstep's view of the node --------------------------------------------------------------------

    def _driven(self) -> Collection[int]:
        """The robots with a controller (a matched publisher on wheel_cmd or cmd_vel, or a swarm controller that
        named them): lockstep waits for them (asked once a step: no sorting, no copy of a swarm's robots when no
        robot has a controller of its own)."""
        driven = np.flatnonzero(self._matches[:, CONTROLLERS].any(axis=1)).tolist()
        if self._swarm is None:
            return driven
        swarm = self._swarm.driven()
        return swarm.union(driven) if driven else swarm

    def _controller(self, robot: int) -> Controller:
        """What lockstep may expect of a driven robot's controller before its first answer."""
        return self.ports[robot].controller(self._declared.get(robot))

    def _stepping(self) -> bool:
        return self._running.is_set() and not self._controls.idle()


def publish_world(node: Node, world: World, frame_prefix: str) -> None:
    """The world, latched: as YAML, and as markers for RViz (also into a headless trial's bag)."""
    quiet_publisher(node, String, 'world', LATCHED).publish(
        String(data=yaml.safe_dump(world.to_dict(), sort_keys=False)))
    quiet_publisher(node, MarkerArray, 'world_markers', LATCHED).publish(
        world_markers(world, frame_prefix + WORLD_FRAME))


def _frame_prefix(value: str) -> str:
    """The `frame_prefix` parameter as frames take it: `sim1` as `sim1/` (frames sim1/odom, not sim1odom)."""
    try:
        return frame_prefix(value)
    except ValueError as error:
        raise PrefixError(f'frame_prefix: {error}') from None


def _world(values: dict) -> World:
    """The world the parameters name, with its robots placed if `robots` asks for a number of them."""
    world = load_world(values['world']) if values['world'] else default_world()
    return place_robots(world, values['robots'], values['seed']) if values['robots'] > 0 else world


def publication_mode(argv: list[str]) -> str:
    """Fast DDS's publication mode for this process (read when the participant is made, before any parameter).

    Free-running, Fast DDS sends from its own thread instead of inside publish(): the loop thread is then free to
    step while the sends go out, which is faster with many robots (benchmarks/bench_sim_node.py). In lockstep
    nothing runs while the controllers answer, so that hand-off to another thread is only one more wake-up per
    message on the round trip: synchronous sending makes the loop faster (alternating runs of
    benchmarks/bench_lockstep.py with RMW_FASTRTPS_PUBLICATION_MODE set each way). Only `-p lockstep:=...` on
    the command line (what `bringup` passes) is looked at; lockstep from a parameter file runs the same,
    asynchronously."""
    return 'SYNCHRONOUS' if command_line_value(argv, 'lockstep') is True else 'ASYNCHRONOUS'


def _senses(value: str) -> frozenset[str]:
    """The `senses` parameter's words; an unknown one is a SenseError naming it."""
    words = frozenset(word.strip() for word in value.split(',') if word.strip())
    unknown = sorted(words - set(SENSE_TOPICS))
    if unknown:
        raise SenseError(f'senses: unknown sense {unknown[0]!r} (senses: {", ".join(SENSE_TOPICS)})')
    return words


class PrefixError(ValueError):
    """A `frame_prefix` that is no ROS names separated by slashes; the message says so."""


class StartInterrupted(Exception):
    """Ctrl-C or SIGTERM came while the node was still being built."""


def _stop_if_asked() -> None:
    """Between two robots' ports and before each phase of the start-up (seconds each for a big swarm): Ctrl-C or
    SIGTERM stops it now, not once the node is built."""
    if shutdown_requested():
        raise StartInterrupted()


DESTROY_UP_TO = 50
"""Robots up to which the node's entities are destroyed one by one at exit, as the anchors do; beyond, the process
ends without it (a swarm's thousands of publishers and subscriptions take many seconds to destroy one by one, and
SIGTERM must end it at once: test_multi_robot_nodes' swarm stop test): the other participants drop ours after the
lease of the package's DDS profile."""


def main(args: list[str] | None = None) -> None:
    started = time.monotonic()
    argv = prepare_arguments(args, SIM_PARAMETERS, USAGE)
    use_no_local_profile()
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
        # command: less CPU per lockstep step (benchmarks/bench_lockstep.py prints each process's CPU per step).
        spin_until_shutdown(node, until=lambda: bool(node.refusal), executor_type=EventsExecutor)
        if node.refusal:
            print(f'sim: cannot start: {node.refusal}', file=sys.stderr)
            code = 2
    except (WorldError, ParameterException, SenseError, PrefixError) as error:
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
