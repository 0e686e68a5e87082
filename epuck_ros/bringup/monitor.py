"""`bringup`'s own ROS node: what the graph says (who is up, who is connected, who else is simulating)
and what the run did (simulated time, every ground-truth sample of every robot, the sim's world).

Readiness comes only from what ROS exposes (the graph, services, latched messages), never from the
children's log lines, so rewording a log line cannot break `bringup`.
"""
from __future__ import annotations

import math
import os
import time
from functools import partial
from pathlib import Path

import numpy as np
import rclpy
import yaml
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Odometry
from rclpy.context import Context
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient
from rclpy.task import Future
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from epuck_ros.bag.cdr import odometry_fields
from epuck_ros.bag.tally import RunTally
from epuck_ros.bringup.swarm_follow import SwarmFollower
from epuck_ros.conversions import nanoseconds_from_seconds, seconds_from_stamp
from epuck_ros.integrity import STATUS_TOPIC, Integrity, integrity_from
from epuck_ros.ros.announcements import SIMULATORS_TOPIC, Announcement, parse_announcement
from epuck_ros.ros.dds_profile import use_package_profile, warn_if_not_fast_dds
from epuck_ros.ros.qos import ANNOUNCEMENT_QOS, CLOCK_KEPT, EVERY_STEP, LATCHED
from epuck_ros.ros.recorder_heard import HeardReader
from epuck_ros.ros.robot_ports import topic_prefix
from epuck_ros.ros.sense_ports import RECORDER_NODE
from epuck_ros.swarm_messages import COMMAND_TOPIC as SWARM_COMMAND_TOPIC
from epuck_ros.world import World, WorldError, world_from_dict

SIM_NODE = 'sim'
VIEW_NODE = 'view'
COMMAND_TOPICS = ('wheel_cmd', 'cmd_vel')
TAKE_PERIOD = 0.5
"""Wall seconds of spinning after which the monitor also takes what waits in its readers itself (see `spin`)."""
CLOCK_RENEW = 2.0
"""Wall seconds without a `/clock` message, once the run has ticked, after which the monitor's `/clock` reader is
made anew (`_renew_stalled_clock`). In suite runs beside a busy loop per core, a monitor that had not read for
thousands of steps had a `/clock` reader that got nothing more after 240 s of 384, for 600 s, with nothing waiting in
it, while the simulator had gone on to its end and paused there; a new reader got the ticks up to 384 at once
(transient local: the last ticks are kept for it). The cause, in Fast DDS or rclpy, was not found."""
REQUEST_RETRY = 2.0
"""Wall seconds after which a parameter request to the simulator is sent again (setting `paused` twice is harmless):
a first request to a service just discovered can go unanswered, its response's way back not yet matched (seen now
and then by benchmarks/bench_lockstep.py, before it retried too)."""


def robot_topic(world: World, robot: str, topic: str) -> str:
    """A robot's topic relative to the simulator's namespace (the simulator's own naming rule)."""
    return topic_prefix(robot, len(world.robots) > 1) + topic


class SwarmSteps:
    """Every robot's ground truth of each whole step a swarm's observation brought, kept as it came (one array a
    step): a robot's samples are read out of it at the end, not appended robot by robot at every step."""

    def __init__(self) -> None:
        self.stamps: list[int] = []
        self.truth: list[np.ndarray] = []
        """Per step, (N, 3) x, y, yaw."""


class RobotTrack:
    """Feeds one robot's ground-truth samples to the run's tally, decoded from the raw CDR as the bag reader does;
    with several robots they come mostly as whole steps (`steps`, row `row`), fed by the monitor."""

    def __init__(self, tally: RunTally, name: str, label: str, steps: SwarmSteps | None = None, row: int = 0) -> None:
        self._add, self.label = tally.add, label
        self.name = name
        self._steps, self._row = steps, row
        self._stamps: set[int] = set()
        self._samples: list[tuple[int, float, float, float]] = []

    @property
    def stamps(self) -> set[int]:
        """Each sample's stamp in ns."""
        return self._stamps if self._steps is None else self._stamps.union(self._steps.stamps)

    @property
    def samples(self) -> list[tuple[int, float, float, float]]:
        """(stamp ns, x, y, yaw) as received: the shape driven, classified at the end as `bag summary` does."""
        if self._steps is None:
            return self._samples
        row, steps = self._row, self._steps
        return self._samples + [(stamp, *truth[row].tolist()) for stamp, truth in zip(steps.stamps, steps.truth)]

    def add(self, data: bytes) -> None:
        stamp, x, y, yaw, _, _ = odometry_fields(data, 0)
        self.add_sample(stamp, x, y, yaw)

    def add_sample(self, stamp: int, x: float, y: float, yaw: float) -> None:
        self._stamps.add(stamp)
        self._samples.append((stamp, x, y, yaw))
        self._add(self.label, stamp, x, y, yaw)


class RunMonitor:
    """Follows the graph, `/clock`, the sim's `world` and each robot's `ground_truth`."""

    def __init__(self, namespace: str, sim_enclave: str, follow_robots: bool = True) -> None:
        """`follow_robots`: tally every robot's ground truth (not needed when the run is recorded: the bag holds
        it, and each reliable reader is one more the simulator waits for)."""
        use_package_profile()   # before our participant; the children inherit it
        self.context = Context()
        remap = ['-r', f'__ns:=/{namespace.strip("/")}'] if namespace else []
        rclpy.init(args=['--ros-args', *remap], context=self.context,
                   signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
        self.node = Node('bringup', context=self.context, enable_rosout=False)
        warn_if_not_fast_dds(self.node.get_logger())
        self.created = time.monotonic()
        """Since when this node (its DDS participant) watches the domain."""
        # Every step brings /clock and each robot's ground truth: rclpy's EventsExecutor dispatches them from C++
        # instead of rebuilding a wait set in Python before each one (see benchmarks/bench_bringup.py).
        self._executor = EventsExecutor(context=self.context)
        self._executor.add_node(self.node)
        self.sim_time = 0.0
        self._spin_until = math.inf
        self._reached = Future()
        """Done once `/clock` reached `_spin_until`: ends the current `spin`."""
        self.clock_messages = 0
        """/clock messages received: any before `bringup` resumes its (paused, silent) simulator are another's."""
        self.first_tick: tuple[float, float] | None = None
        self.longest_stall: tuple[float, float] = (0.0, 0.0)
        """(wall s, simulated s at its start) of the longest wait between two ticks that advanced simulated time:
        lockstep waiting for an answer, a re-sent first step, the machine stalled."""
        self.last_tick: tuple[float, float] | None = None
        """(monotonic wall time, simulated time) of the first and the last `/clock` message."""
        self.world: World | None = None
        self.world_error = ''
        self.tracks: dict[str, RobotTrack] = {}
        self.tally: RunTally | None = None
        """Distance and contacts of every robot so far (the same tally `bag summary` makes from a bag)."""
        self._follow_robots = follow_robots
        self._followers_matched = not follow_robots   # the simulator knows our ground-truth readers (`_on_world`)
        self.sim_enclave = sim_enclave
        """The enclave our simulator was started with: how the graph tells it from another node called sim."""
        self.announcements: set[Announcement] = set()
        """Every simulator that announced itself on this domain (ours among them once it is up)."""
        self.integrity: Integrity | None = None
        """Whether the run is reproducible, as the simulator's latched lockstep_status last said."""
        self._controllers: dict[str, list[tuple[str, str]]] = {}
        """Each robot's controllers, once seen connected: the graph is asked again only about the others (each look
        reads the whole graph, a swarm's tens of thousands of endpoints)."""
        self._recorded: set[str] = set()
        """The topics the recorder was seen subscribed to (asked again only about the others, as above)."""
        self._parameters = AsyncParameterClient(self.node, SIM_NODE)
        self._subscribe()
        self._swarm = SwarmFollower(self.node)
        self._recorder_heard = HeardReader(self.node)

    def _subscribe(self) -> None:
        """What every run is followed by: /clock, the simulator's world and lockstep status, the announcements."""
        self._make_clock_reader()
        self.node.create_subscription(String, 'world', self._on_world, LATCHED)
        self.node.create_subscription(DiagnosticStatus, STATUS_TOPIC, self._on_status, LATCHED)
        self.node.create_subscription(String, SIMULATORS_TOPIC, self._on_announcement, ANNOUNCEMENT_QOS)

    # --- what the run did -------------------------------------------------------------------------------
    def _on_status(self, msg: DiagnosticStatus) -> None:
        self.integrity = integrity_from(msg.message, {value.key: value.value for value in msg.values})

    def _make_clock_reader(self) -> None:
        """A `/clock` reader; a new one (`_renew_stalled_clock`) drops the ticks kept for it up to the latest heard."""
        heard = self.sim_time if self.last_tick is not None else -math.inf
        self._clock_made = time.monotonic()
        self._clock_reader = self.node.create_subscription(Clock, '/clock', partial(self._on_clock, heard), CLOCK_KEPT)

    def _renew_stalled_clock(self) -> None:
        """Make the `/clock` reader anew once it has heard nothing for CLOCK_RENEW since the last tick (none before
        the first: a paused simulator is silent) or since it was made."""
        if self.last_tick is None or time.monotonic() - max(self.last_tick[0], self._clock_made) < CLOCK_RENEW:
            return
        self.node.destroy_subscription(self._clock_reader)
        self._make_clock_reader()

    def _on_clock(self, heard: float, msg: Clock) -> None:
        sim_time = seconds_from_stamp(msg.clock.sec, msg.clock.nanosec)
        if sim_time <= heard:   # kept for a new reader, heard already by the one before
            return
        self.sim_time = sim_time
        self.clock_messages += 1
        if self.last_tick is not None and self.sim_time > self._advanced[1]:
            stall = time.monotonic() - self._advanced[0]
            if stall > self.longest_stall[0]:
                self.longest_stall = (stall, self._advanced[1])
        if self.last_tick is None or self.sim_time > self._advanced[1]:
            self._advanced = (time.monotonic(), self.sim_time)
        self.last_tick = (time.monotonic(), self.sim_time)
        if self.first_tick is None:
            self.first_tick = self.last_tick
        if self.sim_time >= self._spin_until - 1e-6 and not self._reached.done():
            self._reached.set_result(None)

    def stepping_speed(self) -> float | None:
        """Simulated seconds per wall second from the first `/clock` to the last: the run's pace once stepping,
        without the run's start-up (a simulator still in its discovery window at the resume steps later)."""
        if self.first_tick is None or self.last_tick is None or self.last_tick[0] <= self.first_tick[0]:
            return None
        (wall0, sim0), (wall1, sim1) = self.first_tick, self.last_tick
        return (sim1 - sim0) / (wall1 - wall0)

    def _on_announcement(self, msg: String) -> None:
        announced = parse_announcement(msg.data)
        if announced is not None:
            self.announcements.add(announced)

    def _on_world(self, msg: String) -> None:
        if self.world is not None:
            return
        try:
            self.world = world_from_dict(yaml.safe_load(msg.data) or {}, source='the sim\'s world topic')
        except (WorldError, yaml.YAMLError) as error:
            self.world_error = str(error)
            return
        if not self._follow_robots:
            return
        several = len(self.world.robots) > 1
        # Labelled as a bag names its robots: by namespace, '' for a lone robot's topics.
        labels = [name if several else '' for name in self.world.names]
        self.tally = RunTally(labels, self.world)
        steps = SwarmSteps() if several else None
        for row, (name, label) in enumerate(zip(self.world.names, labels)):
            track = self.tracks[name] = RobotTrack(self.tally, name, label, steps, row)
            # Every step, the simulator waiting for this reader (EVERY_STEP): the summary is the run's.
            if not several:   # several: all in one message per step
                self.node.create_subscription(Odometry, robot_topic(self.world, name, 'ground_truth'), track.add,
                                              EVERY_STEP, raw=True)
        if several:
            self._swarm.follow(self.world.names, partial(self._on_swarm_step, steps), EVERY_STEP)
        # The world again, on a reader made after those: DDS announces a participant's readers in the order they are
        # made, so the simulator knows them all once it sends its latched world to this one. Without it, a loaded
        # run's simulator could take its first step before it knew of them and leave it out of the summary.
        self.node.create_subscription(String, 'world', self._on_followers_matched, LATCHED)

    def _on_followers_matched(self, _: String) -> None:
        self._followers_matched = True

    def _on_swarm_step(self, steps: SwarmSteps, stamp: int, truth: np.ndarray) -> None:
        """Every robot's ground truth of a step, into the tally at once (`RunTally.add_step`); robot by robot when
        the step lacks some."""
        present = ~np.isnan(truth[:, 0])
        if present.all():
            steps.stamps.append(stamp)
            steps.truth.append(truth)
            self.tally.add_step(stamp, truth[:, 0], truth[:, 1], truth[:, 2])
            return
        tracks = list(self.tracks.values())
        for row in np.flatnonzero(present).tolist():
            tracks[row].add_sample(stamp, *truth[row].tolist())

    def spin(self, timeout: float, until_sim_time: float = math.inf) -> None:
        """Take what arrives for `timeout` wall seconds, or until `/clock` reaches `until_sim_time`.

        The executor runs the callbacks from C++ all that time. A run brings `/clock` and each robot's ground truth
        every step, and returning to the caller after each of them (`spin_once`, then the caller's checks) made
        this process a slow third party to every lockstep round trip (see bench_bringup in the README)."""
        self._spin_until = until_sim_time
        self._reached = Future()
        deadline = time.monotonic() + timeout
        while self.sim_time < until_sim_time - 1e-6 and (left := deadline - time.monotonic()) > 0:
            self._executor.spin_until_future_complete(self._reached, timeout_sec=min(TAKE_PERIOD, left))
            self._take_waiting()
            self._renew_stalled_clock()

    def catch_up(self, timeout: float) -> None:
        """Take the samples still on their way: until every robot's truth reached the last `/clock` (bounded)."""
        last = nanoseconds_from_seconds(self.sim_time)
        deadline = time.monotonic() + timeout
        while any(not track.stamps or max(track.stamps) < last for track in self.tracks.values()) and \
                time.monotonic() < deadline:
            self._take_waiting()
            self._executor.spin_once(timeout_sec=0.01)

    def _take_waiting(self) -> None:
        """Take every message waiting in this node's readers and hand it to its callback, as the executor would.

        rclpy's EventsExecutor (experimental in Jazzy) takes a message when an event says one came. When the
        monitor's `/clock` stalled (CLOCK_RENEW) a lost event was suspected first, and a reader is asked here every
        TAKE_PERIOD, events or not (a later event finds nothing left and the executor goes on). That did not cure the
        stall, whose reader held nothing; it stays as the guard against a lost event it was made for."""
        for subscription in list(self.node.subscriptions):
            with subscription.handle:
                while (taken := subscription.handle.take_message(subscription.msg_type, subscription.raw)) is not None:
                    subscription.callback(taken[0])

    # --- the graph --------------------------------------------------------------------------------------
    def sim_missing(self) -> str:
        """What our sim has not done yet of being in the graph, publishing its world (so its topics exist) and
        answering parameter requests; '' once it has."""
        if not any(enclave == self.sim_enclave or not self.sim_enclave for _, _, enclave in self._sims()):
            return 'is not in the ROS graph'
        if self.world is None:
            return 'has not published its world'
        if not self._parameters.services_are_ready():
            return 'does not answer parameter requests'
        if not self._followers_matched:
            return 'has not matched bringup\'s readers of the robots\' ground truth'
        return ''

    def graph_progress(self) -> tuple[int, ...]:
        """How far the start-up has come, as the graph shows it: its topics and nodes (a swarm's simulator makes its
        topics, a controller its nodes, for minutes), the controllers and recorded topics found."""
        return (len(self.node.get_topic_names_and_types()), len(self.node.get_node_names_and_namespaces()),
                len(self._controllers), len(self._recorded))

    def _sims(self) -> list[tuple[str, str, str]]:
        return [entry for entry in self.node.get_node_names_and_namespaces_with_enclaves() if entry[0] == SIM_NODE]

    def clock_sources(self) -> list[str]:
        """The nodes publishing `/clock` on this domain (ours is one of them once it is up). One whose name DDS has
        not told yet (`_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_`) is named by the simulators announced, ours
        (a child of this process) left out, with pid and start time."""
        named = [_full_name(info.node_namespace, info.node_name)
                 for info in self.node.get_publishers_info_by_topic('/clock')]
        return unknown_named_by(named, [a for a in sorted(self.announcements) if not _our_child(a)])

    def world_sources(self) -> int:
        """Publishers of the `world` topic (each simulator has one)."""
        return self.node.count_publishers('world')

    def other_simulators(self) -> list[str]:
        """Nodes called `sim` on this domain, whatever their namespace, other than ours."""
        sims = self._sims()
        if not self.sim_enclave:  # no way to tell ours: a second one is another
            return [_full_name(ns, name) for name, ns, _ in sims] if len(sims) > 1 else []
        return [_full_name(ns, name) for name, ns, enclave in sims if enclave != self.sim_enclave]

    def recorder_subscribed(self) -> bool:
        """The recorder subscribes to every topic the simulator publishes, and to the robots' commands that have a
        publisher (a recorded swarm run's first wheel commands were missing: the run began before the recorder had
        subscribed to them). Topics seen subscribed once are not asked about again, and the first one missing ends
        the look."""
        node = self.node
        try:
            published = node.get_publisher_names_and_types_by_node(SIM_NODE, node.get_namespace())
        except Exception:  # noqa: BLE001 - rclpy raises NodeNameNonExistentError until the node is discovered
            return False
        commands = [] if self.world is None else [node.resolve_topic_name(robot_topic(self.world, robot, topic))
                                                  for robot in self.world.names for topic in COMMAND_TOPICS]
        commands.append(node.resolve_topic_name(SWARM_COMMAND_TOPIC))
        needed = [(topic, True) for topic, _ in published if topic != '/rosout']
        for topic, always in needed + [(topic, False) for topic in commands]:
            if topic in self._recorded:
                continue
            if any(info.node_name == RECORDER_NODE for info in node.get_subscriptions_info_by_topic(topic)):
                self._recorded.add(topic)
            elif always or node.count_publishers(topic):
                return False
        return bool(published)

    def recorder_heard(self) -> bool:
        """The recorder has heard from every controller this node heard declare itself, on its own declaration
        (`swarm/command`) or on lockstep.DECLARATION_TOPIC: their answers reach the bag from the first step
        (ros/recorder_heard.py says why seeing the recorder's readers is not enough)."""
        wanted = set(self._recorder_heard.declared)
        if self._swarm.declared:
            wanted.add(self.node.resolve_topic_name(SWARM_COMMAND_TOPIC))
        return wanted <= self._recorder_heard.topics

    def controllers(self, robot: str) -> list[tuple[str, str]]:
        """(name, namespace) of the nodes publishing `robot`'s wheel_cmd or cmd_vel, once their subscriptions are
        in the graph too (a controller subscribes before it commands). Once found, not looked up again."""
        assert self.world is not None
        if robot in self._controllers:
            return self._controllers[robot]
        found = self._swarm.controllers(robot)   # a swarm controller names its robots: no look per robot
        if found:
            self._controllers[robot] = found
            return found
        for topic in COMMAND_TOPICS:
            for info in self.node.get_publishers_info_by_topic(robot_topic(self.world, robot, topic)):
                try:
                    subscribed = self.node.get_subscriber_names_and_types_by_node(info.node_name, info.node_namespace)
                except Exception:  # noqa: BLE001 - not discovered yet
                    continue
                if subscribed:
                    found.append((info.node_name, info.node_namespace))
        if found:
            self._controllers[robot] = found
        return found

    def view_serving(self) -> bool:
        """The view subscribes to `world` once its page is served: its node alone is in the graph earlier (a page
        opened at the printed address as soon as bringup printed it was refused on a loaded machine)."""
        return any(info.node_name == VIEW_NODE for info in self.node.get_subscriptions_info_by_topic('world'))

    def set_paused(self, paused: bool, timeout: float, controllers: int | None = None) -> bool:
        """Set the simulator's `paused` parameter, asking again every REQUEST_RETRY; True once it said yes. With
        `controllers`, a lockstep simulator's first step waits until it sees that many (`lockstep_controllers`)."""
        deadline = time.monotonic() + timeout
        wanted = [Parameter('lockstep_controllers', value=controllers)] if controllers is not None else []
        while True:
            future = self._parameters.set_parameters(wanted + [Parameter('paused', value=paused)])
            self._executor.spin_until_future_complete(
                future, timeout_sec=max(0.0, min(REQUEST_RETRY, deadline - time.monotonic())))
            if future.done():
                return all(r.successful for r in future.result().results)
            if time.monotonic() >= deadline:
                return False

    def close(self) -> None:
        self._executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _full_name(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'


UNKNOWN_NODE = '_NODE_NAME_UNKNOWN_'
"""rmw's name for a node whose name discovery has not brought yet."""


def unknown_named_by(names: list[str], announced: list[Announcement]) -> list[str]:
    """`names` of nodes, those not known yet replaced by who the other simulators `announced` are (pid and start
    time), or said to be unnamed so far: a refusal named `_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_`."""
    known = [name for name in names if not name.endswith(UNKNOWN_NODE)]
    if len(known) == len(names):
        return names
    return known + ([a.describe() for a in announced] or ['a node not yet known by name'])


def _our_child(announced: Announcement) -> bool:
    """The announcement is that of a process this one started (our simulator)."""
    try:
        parent = int(Path(f'/proc/{announced.pid}/stat').read_text().rsplit(')', 1)[1].split()[1])
    except (OSError, IndexError, ValueError):
        return False
    return announced.is_process(announced.pid) and parent == os.getpid()


def samples_missing(track: RobotTrack, time_step: float, end_time: float) -> int:
    """Steps up to `end_time` of which no ground-truth sample arrived (the first step is at `time_step`)."""
    steps = {round(stamp * 1e-9 / time_step) for stamp in track.stamps}
    return max(0, int(math.floor(end_time / time_step + 1e-6)) - len(steps))
