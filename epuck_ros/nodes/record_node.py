"""`record`: records topics to a rosbag2-compatible MCAP bag, used like ``ros2 bag record``.

    record [-o DIR] [--compression none|zstd|lz4] [--max-duration S] [TOPIC ...] [--ros-args ...]

Topics (all visible ones when none is named) are found from the graph every `DISCOVERY_PERIOD` seconds, so topics that
appear later are recorded too. The simulator's on-demand sense topics (camera, ground and light sensors, IMU:
`ros/sense_ports.py`; the e-puck interface's: `ros/interface_ports.py`) are recorded as they are published, without
asking for them: the simulator computes a sense while something else reads it (a controller, the view, an echo) or its
`senses` parameter says so, and a recorder alone must not make it render a camera every step. Such a topic enters the
bag with its first message. `--senses` / `--all-senses` (or naming the topic) ask for them: those subscriptions are
made by a second node, `SENSE_ASKER_NODE`, which the simulator counts as a reader that asks. Messages are subscribed
raw — the CDR bytes go to the bag untouched — with a QoS that matches every publisher, and a thread writes the bag so
callbacks only enqueue. publish_time is the publisher's source timestamp, as rosbag2 records it.

log_time: under ``use_sim_time``, a message that names a simulator step (`epuck_ros.bag.steps`: a header stamp, a
TF's, a `stamp=` label) is logged at that step's simulated time, whenever it arrived; any other message at the node's
clock (simulated time), as rosbag2 does. A lockstep run's bag is then a function of the run: the same log times and
messages every time, those of the headless trial (`experiments/recording.py`). For the same reason a step message
received twice with the same bytes (the simulator sends a first step again to a controller that has not answered it)
is recorded once, and the answers (`wheel_cmd`, `cmd_vel`) to the last recorded step are left out: they drive
nothing, and whether they arrived before the recording stopped was a matter of timing. Without ``use_sim_time``
log_time is the wall clock.

Which controllers' answer topics it has heard from (`ros/recorder_heard.py`) it says, latched, on the hidden
`/_recorder/heard`: `bringup` resumes a recorded run once that includes every controller that declared itself.

At the end it says what may be missing: samples DDS reported lost (message-lost events) and gaps
in the header stamps of the bag it wrote (`epuck_ros.bag.gaps`, the same check as ``bag info``).
If the bag cannot be written (a full disk), it stops with one line and exit code 1; the bag then
holds every chunk completed before the failure.
"""
from __future__ import annotations

import argparse
import importlib
import math
import signal
import sys
import threading
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidTopicNameException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.event_handler import QoSMessageLostInfo, SubscriptionEventCallbacks, UnsupportedEventTypeError
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rclpy.qos import QoSProfile
from std_msgs.msg import String
from rclpy.topic_or_service_is_hidden import topic_or_service_is_hidden
from rclpy.utilities import remove_ros_args
from rclpy.validate_topic_name import validate_topic_name

from epuck_ros.bag.gaps import bag_gaps
from epuck_ros.bag.msgdefs import message_definition
from epuck_ros.bag.steps import StepReader, is_answer_topic, step_reader
from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.bag.writer import COMPRESSIONS, BackgroundWriter, BagExistsError, BagWriteError, BagWriter
from epuck_ros.exit_codes import EXIT_FAILED, refuse
from epuck_ros.lockstep import DECLARATION_TOPIC, read_declaration
from epuck_ros.ros.dds_profile import use_package_profile, warn_if_not_fast_dds
from epuck_ros.ros.interface_ports import INTERFACE_TOPICS
from epuck_ros.ros.qos import DECLARATIONS_READ, matching
from epuck_ros.ros.recorder_heard import HeardPublisher
from epuck_ros.ros.sense_ports import ON_DEMAND_TOPICS, RECORDER_NODE, SENSE_TOPICS

DISCOVERY_PERIOD = 0.2
"""s of wall time between two looks at the graph (rosbag2 polls every 0.1 s)."""
SUBSCRIPTION_DEPTH = 1000
"""Messages DDS may hold for the recorder while it is busy: bursts must never overflow it."""
STOP_LATENCY = 0.1
"""Wall seconds the spin waits for a message at most before it looks at the stop flag again."""
DRAIN_LIMIT = 5.0
"""s of wall time the recorder keeps taking messages DDS holds for it after Ctrl-C (the sim may still run);
well within the 10 s bringup allows a child to stop."""
DRAIN_IDLE_SPINS = 3
"""Spins without a message that end that draining (a timer may take a spin)."""
BACKLOG_PER_CALLBACK = 256
"""Messages a callback takes at most beyond its own (see `Recorder._on_message`): enough for any topic's backlog of
a turn, and a topic that arrives faster than it is written cannot hold the executor (the stop flag, the others)."""
NOTHING_RECORDED_WARNING = 5.0
"""s of wall time without a single message before `record` says it may be on the wrong domain."""
EVERY_NODES_TOPICS = frozenset({'/parameter_events', '/rosout'})
"""Topics every node has (the recorder's own too): seen, they say nothing of a simulator on the domain."""
SENSE_ASKER_NODE = 'recorder_senses'
"""The recorder's node for the sense topics it asks for (`--senses`, a named sense topic): any node but RECORDER_NODE
makes the simulator compute a sense it reads."""
DEFAULT_BAG_FOLDER = Path('bags')
STEP_AHEAD_LIMIT_NS = 60 * 10**9
"""A message naming a step this far (simulated ns) beyond the recorder's clock is logged at the clock instead: no
publisher on the domain can put a message hours into a bag's future (a player would wait for it)."""
CLOCK_TOPIC = '/clock'
SAME_STEP_REMEMBERED = 1024
"""Messages of one topic's latest step remembered to drop a copy sent again: a step has a few (8 on `proximity`); a
publisher that names one step for ever cannot grow the recorder's memory."""


def default_output() -> Path:
    """``bags/rosbag2_YYYY_MM_DD-HH_MM_SS``, rosbag2's default name under the project's bag folder."""
    return DEFAULT_BAG_FOLDER / time.strftime('rosbag2_%Y_%m_%d-%H_%M_%S')


def offered_profile(qos: QoSProfile) -> QosProfile:
    """A publisher's QoS (as the graph reports it) in the bag's plain form."""
    return QosProfile(
        history=qos.history.name.lower(), depth=qos.depth, reliability=qos.reliability.name.lower(),
        durability=qos.durability.name.lower(), deadline_ns=qos.deadline.nanoseconds,
        lifespan_ns=qos.lifespan.nanoseconds, liveliness=qos.liveliness.name.lower(),
        liveliness_lease_duration_ns=qos.liveliness_lease_duration.nanoseconds,
        avoid_ros_namespace_conventions=qos.avoid_ros_namespace_conventions)


def subscription_qos(offered: list[QoSProfile]) -> QoSProfile:
    """Compatible with every publisher: reliable / transient_local only if all of them offer it.

    Reliable topics are taken KEEP_ALL: DDS then acknowledges a sample only once the recorder has room for it, so
    a publisher that waits for acknowledgements (the simulator, see `epuck_ros.ros.ack_window`) waits for the
    recorder instead of the recorder's queue overwriting what it has not written yet (KEEP_LAST lost much of
    `proximity` at `real_time_factor` 0)."""
    return matching(offered, SUBSCRIPTION_DEPTH, keep_all=True)


def sense_of(topic: str) -> str | None:
    """Which on-demand sense topic `topic` is (a key of sense_ports.ON_DEMAND_TOPICS, or a topic of the e-puck
    interface, interface_ports.INTERFACE_TOPICS; any robot's), None for others."""
    return next((kind for kind, name in _ON_DEMAND if topic == '/' + name or topic.endswith('/' + name)), None)


_ON_DEMAND = [*ON_DEMAND_TOPICS.items(), *((kind, kind) for kind in INTERFACE_TOPICS)]


def message_class(type_name: str) -> type:
    """``pkg/msg/Type`` -> the generated Python class (raw subscriptions still need its type support)."""
    package, _, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


class Recorder(Node):
    """Subscribes to the wanted topics as they appear and hands every message to the bag writer."""

    def __init__(self, writer: BagWriter, topics: list[str], max_duration: float | None,
                 senses: frozenset[str] = frozenset()) -> None:
        """`senses`: the on-demand senses (keys of sense_ports.SENSE_TOPICS) to ask the simulator for; a named sense
        topic is asked for too."""
        # No /rosout: the recorder's own log lines would end up in the bag, and its closing line
        # would fail to publish once Ctrl-C has shut the context down.
        super().__init__(RECORDER_NODE, enable_rosout=False)
        self._bag = BackgroundWriter(writer)
        self._wanted = {self.resolve_topic_name(t) for t in topics} or None
        self._senses = senses
        self.asker = self._sense_asker()
        self._unregistered: dict[str, tuple[str, list[QosProfile]]] = {}
        """Sense topics recorded without asking, not in the bag until their first message: (type, offered QoS)."""
        self._max_duration_ns = None if max_duration is None else int(max_duration * 1e9)
        self._first_ns: int | None = None
        self._use_sim_time = self.get_parameter('use_sim_time').value
        self._before_clock: list[tuple[str, bytes, int]] = []
        self._recording: set[str] = set()
        self._subscription_of: dict[str, Subscription] = {}
        self._answer_topics: set[str] = set()   # those recorded that carry controllers' answers (is_answer_topic)
        self._heard = HeardPublisher(self)   # those whose controllers matched the recorder (ros/recorder_heard.py)
        self._confirming: Subscription | None = None
        """A reader of the declarations made after the latest answer topic's (`_confirm_after`)."""
        self._skipped: set[str] = set()
        self._lost: dict[str, int] = {}
        """Samples DDS reported lost per topic (message-lost events)."""
        self._step_of: dict[str, StepReader] = {}
        """Under use_sim_time, how to read the step a topic's messages name (its types that name one)."""
        self._latest_step: dict[str, tuple[int, set[int]]] = {}
        """Per step topic, its latest step and the hashes of its messages of that step written (a copy sent again is
        recorded once), at most SAME_STEP_REMEMBERED of them."""
        self._last_clock: int | None = None
        self._latest_named = 0
        """The latest step any message recorded so far named: the simulator is there at least, whatever the node's
        clock says (its /clock subscription may lag seconds behind under load)."""
        self._answers: dict[str, list[tuple[int | None, bytes, int, int]]] = {}
        """Per answer topic, the answers naming a step no later /clock has followed yet and what came after them, in
        order: (step or None, data, publish time, log time)."""
        self.answers_left_out = 0
        self.received = 0
        self.domain_id = self.context.get_domain_id()
        self._started = time.monotonic()
        self._warned_idle = False
        self.failure: str | None = None
        """Why recording had to stop (the bag could not be written); None while all is well."""
        self.finished = False
        """True once --max-duration of the node's clock has been recorded. A plain flag, not a Future:
        rclpy 7.1's spin_until_future_complete adds a callback to the future on every spin, so a
        recording of N messages would keep N callbacks alive (ros2/rclpy#1371)."""
        self._start_discovery(writer.path)

    def _sense_asker(self) -> Node | None:
        """The node of the sense subscriptions that ask for their sense (see the module), when there will be any."""
        if not (self._senses or any(sense_of(topic) for topic in self._wanted or ())):
            return None
        return Node(SENSE_ASKER_NODE, context=self.context, enable_rosout=False, start_parameter_services=False)

    def _start_discovery(self, path: Path) -> None:
        """Look at the graph now and every DISCOVERY_PERIOD, and say where the recording goes."""
        # A steady-clock timer: discovery must run before /clock ticks under use_sim_time.
        self.create_timer(DISCOVERY_PERIOD, self._discover, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self._discover()
        self.get_logger().info(f'Recording to {path} on ROS_DOMAIN_ID={self.domain_id}: '
                               f'{"all topics" if self._wanted is None else ", ".join(sorted(self._wanted))}')

    def _discover(self) -> None:
        if self._bag.error is not None:
            self.failure = f'{self._bag.writer.path}: bag writing failed: {self._bag.error}'
            self.finished = True
            return
        self._warn_if_idle()
        answers = len(self._answer_topics)
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recording or topic in self._skipped:
                continue
            if self._wanted is None and topic_or_service_is_hidden(topic):
                continue
            if self._wanted is not None and topic not in self._wanted:
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue
            self._subscribe(topic, types, [p.qos_profile for p in publishers])
        if len(self._answer_topics) > answers:
            self._confirm_after(frozenset(self._answer_topics))

    def _confirm_after(self, answer_topics: frozenset[str]) -> None:
        """A new reader of the controllers' declarations, made after the readers of `answer_topics`: a declaration
        it receives proves the declaring process knows those readers too (ros/recorder_heard.py says why)."""
        if self._confirming is not None:
            self.destroy_subscription(self._confirming)

        def on_declaration(message: String) -> None:
            try:
                _, topics = read_declaration(message.data)
            except ValueError:   # the simulator says why it refuses one; the recorder records it as it came
                return
            self._heard.add(topic for topic in topics if topic in answer_topics)
        self._confirming = self.create_subscription(String, DECLARATION_TOPIC, on_declaration, DECLARATIONS_READ)

    def _subscribe(self, topic: str, types: list[str], offered: list[QoSProfile]) -> None:
        if len(types) != 1:
            self._skip(topic, f'published with several types ({", ".join(types)})')
            return
        try:
            msg_class = message_class(types[0])
        except (ImportError, AttributeError, ValueError):
            self._skip(topic, f'type {types[0]} is not installed here')
            return
        self._recording.add(topic)
        if is_answer_topic(topic):
            self._answer_topics.add(topic)
        if self._use_sim_time:
            reader = step_reader(types[0], message_definition(types[0]).text)
            if reader is not None:
                self._step_of[topic] = reader
        sense = sense_of(topic)
        asked = sense is not None and (sense in self._senses or self._wanted is not None)
        profiles = [offered_profile(q) for q in offered]
        if sense is not None and not asked:
            self._unregistered[topic] = (types[0], profiles)
        else:
            self._bag.add_topic(topic, types[0], profiles)
        node = self.asker if asked else self
        events = SubscriptionEventCallbacks(message_lost=partial(self._on_lost, topic))
        try:
            subscription = node.create_subscription(msg_class, topic, partial(self._on_message, topic),
                                                    subscription_qos(offered), raw=True, event_callbacks=events)
        except UnsupportedEventTypeError:  # an RMW without message-lost events: stamp gaps still tell
            subscription = node.create_subscription(msg_class, topic, partial(self._on_message, topic),
                                                    subscription_qos(offered), raw=True)
        self._subscription_of[topic] = subscription
        how = '' if sense is None else ', asking for it' if asked else ', recorded while something asks for it'
        self.get_logger().info(f'subscribed to {topic} ({types[0]}{how})')

    def _on_lost(self, topic: str, info: QoSMessageLostInfo) -> None:
        self._lost[topic] = self._lost.get(topic, 0) + info.total_count_change

    def _warn_if_idle(self) -> None:
        if self._warned_idle or self.received or time.monotonic() - self._started < NOTHING_RECORDED_WARNING:
            return
        self._warned_idle = True
        if self._recording - EVERY_NODES_TOPICS:
            self.get_logger().warning(
                f'no message on {", ".join(sorted(self._recording))} after {NOTHING_RECORDED_WARNING:.0f} s '
                f'on ROS_DOMAIN_ID={self.domain_id}; is the simulator running?')
        else:
            wanted = 'no topics seen' if self._wanted is None else f'none of {", ".join(sorted(self._wanted))} seen'
            self.get_logger().warning(f'{wanted} on ROS_DOMAIN_ID={self.domain_id} after '
                                      f'{NOTHING_RECORDED_WARNING:.0f} s; is the simulator on this domain?')

    def _skip(self, topic: str, reason: str) -> None:
        self._skipped.add(topic)
        self.get_logger().warning(f'not recording {topic}: {reason}')

    def _on_message(self, topic: str, data: bytes, info: dict) -> None:
        """One message, then the others DDS holds for this topic already (up to BACKLOG_PER_CALLBACK). The executor
        takes one message of each ready topic per turn, so a topic of eight messages per step (`proximity`) fell
        behind the others: a lockstep run at real_time_factor 0 left most of its messages unwritten when the
        recording ended (stamps ending early), against none with this."""
        if topic in self._answer_topics and topic not in self._heard.topics:   # its writer has matched the recorder
            self._heard.add([topic])
        self._record(topic, data, info)
        subscription = self._subscription_of[topic]
        for _ in range(BACKLOG_PER_CALLBACK):
            taken = subscription.handle.take_message(subscription.msg_type, True)
            if taken is None:
                return
            self._record(topic, *taken)

    def _record(self, topic: str, data: bytes, info: dict) -> None:
        self.received += 1
        now = self.get_clock().now().nanoseconds
        if self._max_duration_ns is not None and now:
            self._first_ns = now if self._first_ns is None else self._first_ns
            if now - self._first_ns >= self._max_duration_ns:
                self.finished = True
        published = info.get('source_timestamp') or now
        read = self._step_of.get(topic)
        step = None if read is None else read(data)
        if step is not None and step <= now + STEP_AHEAD_LIMIT_NS:
            self._latest_named = max(self._latest_named, step)
            self._record_step(topic, data, step, published)
            return
        if now and self._use_sim_time:
            now = max(now, self._latest_named)
        if self._answers.get(topic):   # behind an answer held (see _record_step): in its order
            self._answers[topic].append((None, data, published, now))
        elif self._use_sim_time and now == 0:
            # Before the first /clock tick sim time reads 0 (rosbag2 #764): hold the message
            # and stamp it with the first simulated time instead.
            self._before_clock.append((topic, data, info.get('source_timestamp') or 0))
        else:
            if self._before_clock:
                self._write_held(now)
            self._write(topic, data, now, published)

    def _record_step(self, topic: str, data: bytes, step: int, published: int) -> None:
        """A message of step `step`, logged at it: once (a copy sent again is not), an answer once a later /clock
        has come. Messages held from before the first /clock go first, at this step."""
        if self._before_clock:
            self._write_held(step)
        latest, written = self._latest_step.get(topic, (-1, set()))
        digest = hash(data)
        if step == latest and digest in written:
            return
        if step > latest:
            latest, written = step, set()
            self._latest_step[topic] = (latest, written)
        if step == latest and len(written) < SAME_STEP_REMEMBERED:
            written.add(digest)
        if is_answer_topic(topic) and CLOCK_TOPIC in self._recording and \
                (self._last_clock is None or step >= self._last_clock or self._answers.get(topic)):
            self._answers.setdefault(topic, []).append((step, data, published, step))
            return
        self._write(topic, data, step, published)
        if topic == CLOCK_TOPIC and (self._last_clock is None or step > self._last_clock):
            self._last_clock = step
            self._release_answers(lambda named: named < step)

    def _release_answers(self, followed: Callable[[int], bool]) -> None:
        """Write each topic's held answers from the first on while they name a `followed` step (or none)."""
        for topic, held in self._answers.items():
            released = next((index for index, (named, *_) in enumerate(held)
                             if named is not None and not followed(named)), len(held))
            for _, data, published, log_time in held[:released]:
                self._write(topic, data, log_time, published)
            del held[:released]

    def _write_held(self, stamp: int) -> None:
        for topic, data, published in self._before_clock:
            self._write(topic, data, stamp, published or stamp)
        self._before_clock.clear()

    def _write(self, topic: str, data: bytes, log_time: int, publish_time: int) -> None:
        if topic in self._unregistered:   # a sense topic's first message: into the bag from now on
            self._bag.add_topic(topic, *self._unregistered.pop(topic))
        self._bag.write(topic, data, log_time, publish_time)

    def destroy_node(self) -> None:
        if self.asker is not None:
            self.asker.destroy_node()
        super().destroy_node()

    def close(self) -> None:
        """Write what is queued, the MCAP summary and metadata.yaml; then say what may be missing."""
        if self._before_clock:  # nothing came after the first /clock tick, or no tick at all
            self._write_held(self.get_clock().now().nanoseconds or time.time_ns())
        left = sum(1 for held in self._answers.values() for named, *_ in held if named is not None)
        self._release_answers(lambda named: False)   # the unnamed messages behind them (a behaviour's last stop)
        for topic, held in self._answers.items():
            for named, data, published, log_time in held:
                if named is None:
                    self._write(topic, data, log_time, published)
        self.answers_left_out, self._answers = left, {}
        self._bag.close()
        writer = self._bag.writer
        self.get_logger().info(f'wrote {writer.times.count} messages on {len(writer.topics)} topics '
                               f'to {writer.path}' + (f'; left out {self.answers_left_out} answers to the last '
                                                      'step (they drive nothing)' if self.answers_left_out else ''))
        for line in self.loss_report():
            if line.startswith('lost'):
                self.get_logger().warning(line)
            else:
                self.get_logger().info(line)

    def loss_report(self) -> list[str]:
        """Lines on lost samples (DDS events) and stamp gaps in the bag just written."""
        lost = {topic: count for topic, count in sorted(self._lost.items()) if count}
        lines = [f'lost {count} samples on {topic} (DDS message-lost events)' for topic, count in lost.items()]
        try:
            with Bag(self._bag.writer.path) as bag:
                checked, gaps = bag_gaps(bag)
        except BagError as error:
            return [*lines, f'lost: cannot check the stamps of the bag: {error}']
        lines += [f'lost: {topic_gaps.describe()}' for topic_gaps in gaps]
        if not lines:
            lines.append(f'no message lost: no DDS message-lost event, no gap in the stamps of the {len(checked)} '
                         'periodic stamped and answer topics')
        return lines


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='record', description='Record topics to a rosbag2-compatible MCAP bag (like ros2 bag record).',
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog='It records on the ROS_DOMAIN_ID of its environment (printed at start) and warns if nothing\n'
               f'arrives within {NOTHING_RECORDED_WARNING:.0f} s. At the end it reports lost samples (DDS events) '
               'and stamp gaps.\n'
               'Exit codes: 0 done, 1 the bag could not be written (e.g. disk full), 2 bad arguments or\n'
               'an existing output folder.\n\n'
               'Senses on demand: the simulator computes a camera, ground, light or IMU topic only while\n'
               'something asks for it (a controller that enabled the device, the view, an echo, or the sim\n'
               'parameter senses). record takes such a topic whenever it is published, from its first\n'
               'message on, but does not ask for it, so an IR-only run is recorded without its camera;\n'
               '--senses, --all-senses or naming the topic ask for it (the simulator then renders it).\n\n'
               'examples: record -o bags/manual /odom /ground_truth --ros-args -p use_sim_time:=true\n'
               '          record -o bags/seen --senses camera --ros-args -p use_sim_time:=true')
    parser.add_argument('topics', nargs='*', metavar='TOPIC',
                        help='topics to record (default: all; a sense topic named here is asked for)')
    parser.add_argument('--senses', type=_sense_list, default=frozenset(), metavar='KIND[,KIND]',
                        help=f'ask the simulator for these senses of every robot ({", ".join(SENSE_TOPICS)})')
    parser.add_argument('--all-senses', action='store_true', help='ask the simulator for every sense')
    parser.add_argument('-o', '--output', type=Path,
                        help='bag folder to create (default: bags/rosbag2_YYYY_MM_DD-HH_MM_SS)')
    parser.add_argument('--compression', choices=sorted(COMPRESSIONS), default='none',
                        help='MCAP chunk compression (default: none, as rosbag2)')
    parser.add_argument('--max-duration', type=float, metavar='SECONDS',
                        help="stop after this long on the node's clock (simulated time with use_sim_time)")
    options = parser.parse_args(argv)
    if options.all_senses:
        options.senses = frozenset(SENSE_TOPICS)
    if options.max_duration is not None and not 0 < options.max_duration < math.inf:
        parser.error(f'--max-duration must be a finite positive number of seconds, not {options.max_duration}')
    for topic in options.topics:
        try:
            validate_topic_name(topic)
        except InvalidTopicNameException as error:
            parser.error(f'invalid topic name {topic!r}: {str(error).splitlines()[0]}')
    return options


def _sense_list(text: str) -> frozenset[str]:
    """`--senses camera,ground`: the kinds, each one the simulator has."""
    kinds = frozenset(word.strip() for word in text.split(',') if word.strip())
    unknown = sorted(kinds - set(SENSE_TOPICS))
    if unknown or not kinds:
        raise argparse.ArgumentTypeError(f'{unknown[0] if unknown else text!r} is no sense: '
                                         f'choose from {", ".join(SENSE_TOPICS)}')
    return kinds


def main(args: list[str] | None = None) -> None:
    argv = sys.argv if args is None else args
    options = parse_arguments(remove_ros_args(args=argv)[1:])
    try:
        writer = BagWriter(options.output or default_output(), options.compression)
    except (BagExistsError, OSError) as error:
        refuse(f'record: error: {error}')
    # Ctrl-C / SIGTERM ask to stop rather than shut the context down at once (rclpy's handler): the
    # recorder then takes what DDS already holds for it before closing the bag.
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    use_package_profile()
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    failure = None
    try:
        node = Recorder(writer, options.topics, options.max_duration, options.senses)
        warn_if_not_fast_dds(node.get_logger())
        spin_until_finished(node, stop)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        for signum in (signal.SIGINT, signal.SIGTERM):
            signal.signal(signum, signal.SIG_IGN)  # a second Ctrl-C must not cut the bag short
        try:
            if node is None:
                writer.close()
            else:
                failure = node.failure
                node.close()
        except (BagWriteError, OSError) as error:
            failure = failure or f'{writer.path}: {error}'
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    if failure is not None:
        print(f'record: error: {failure}; the bag keeps every chunk completed before it', file=sys.stderr)
        raise SystemExit(EXIT_FAILED)


def spin_until_finished(node: Recorder, stop: threading.Event | None = None) -> None:
    """Spin until --max-duration is reached, the bag cannot be written, or `stop` is set; after a stop,
    take the messages DDS already holds for the recorder (for at most DRAIN_LIMIT s) so none is lost."""
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    if node.asker is not None:
        executor.add_node(node.asker)
    while not node.finished and not (stop is not None and stop.is_set()) and rclpy.ok():
        executor.spin_once(timeout_sec=STOP_LATENCY)   # a signal does not wake the wait: look at `stop` anyway
    if stop is None or not stop.is_set() or node.failure is not None:
        return
    idle, deadline = 0, time.monotonic() + DRAIN_LIMIT
    while idle < DRAIN_IDLE_SPINS and time.monotonic() < deadline and rclpy.ok():
        before = node.received
        executor.spin_once(timeout_sec=0.05)
        idle = idle + 1 if node.received == before else 0


if __name__ == '__main__':
    main()
