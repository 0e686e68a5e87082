"""`foxglove`: a running simulation live in Foxglove, from a pip install (foxglove_bridge comes only with ROS).

    foxglove [--port PORT] [--host HOST] [--ros-args ...]

A Foxglove WebSocket server (the `foxglove-sdk` package) joins the simulation on this process's ROS domain: every
topic the graph shows with a publisher becomes a channel of the same name (message encoding `cdr`, schema
`ros2msg` with the text a bag carries: `epuck_ros.bag.msgdefs`), robots' namespaced topics and topics that appear
later included; a topic that leaves the graph is withdrawn (so is one only the bridge's own reader kept there; one
that another node still reads stays, as the graph shows it). The messages are the CDR bytes DDS delivered (raw
subscriptions), untouched. `/clock` is the server's time.

A topic is subscribed in ROS only while a Foxglove client subscribes to its channel, as foxglove_bridge does
(foxglove-sdk, ros/src/foxglove_bridge): the simulator renders a camera, reads ground and light sensors and sends
`/tf` only while someone reads them, so a layout without an image panel costs no rendering. The subscription's QoS
is chosen as `ros2 topic echo` and foxglove_bridge choose it (`reading_qos`): a viewer never makes the simulator
wait. A latched topic (robot_description, /tf_static, world) is subscribed again when another client subscribes to
it: DDS hands the new reader every publisher's kept message (the SDK cannot address one client from Python), and
the clients already subscribed get it once more, which for a latched topic changes nothing.

Threads: the SDK calls the listener (`ChannelClients`) from its own threads; it only queues, and the node's
executor thread (rclpy's EventsExecutor) makes and drops the subscriptions and forwards the messages.
"""
from __future__ import annotations

import argparse
import queue
import sys
import time
from dataclasses import dataclass
from functools import lru_cache, partial

import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.serialization import deserialize_message
from rclpy.signals import SignalHandlerOptions
from rclpy.subscription import Subscription
from rclpy.topic_or_service_is_hidden import topic_or_service_is_hidden
from rclpy.utilities import remove_ros_args
from rosgraph_msgs.msg import Clock as ClockMessage

from epuck_ros.bag.msgdefs import message_definition
from epuck_ros.conversions import nanoseconds_from_stamp
from epuck_ros.exit_codes import refuse
from epuck_ros.foxglove.address import DEFAULT_HOST, DEFAULT_PORT, NODE_NAME, address_error, websocket_url
from epuck_ros.loopback import is_loopback
from epuck_ros.ros.dds_profile import use_package_profile, warn_if_not_fast_dds
from epuck_ros.ros.qos import NEWEST_ONLY, matching
from epuck_ros.nodes.record_node import message_class
from epuck_ros.ros.sense_ports import SENSE_TOPICS
from epuck_ros.ros.spinning import spin_until_shutdown

try:
    import foxglove
    from foxglove.websocket import Capability, ChannelView, Client, WebSocketServer
except ImportError:   # a ROS install: rosdep has no key for foxglove-sdk (package.xml), pip installs it
    foxglove = None

CLOCK_TOPIC = '/clock'
DISCOVERY_PERIOD = 0.2
"""Wall seconds between two looks at the graph (the recorder's period)."""
REQUEST_PERIOD = 0.05
"""Wall seconds between two looks at what the clients subscribed to or left (the subscriptions follow that late)."""
TIME_PERIOD = 1 / 60
"""Wall seconds between two broadcasts of the server's time at most: the SDK sends time on the control plane,
whose queue, once full, disconnects the client, and a run at real_time_factor 0 ticks thousands of times a second.
The newest time not yet sent goes out on the next look (`REQUEST_PERIOD`), so the last tick always arrives."""
MAX_DEPTH = 25
"""History a subscription keeps at most, as foxglove_bridge's `max_qos_depth` default."""
SERVER_NAME = 'epuck_ros'


def reading_qos(offered: list[QoSProfile]) -> QoSProfile:
    """The QoS that matches every publisher: reliable, transient local only if all of them offer it; KEEP_LAST as
    deep as their histories together, within [1, MAX_DEPTH] (ros2 topic echo's rule, and foxglove_bridge's).
    A KEEP_LAST reader acknowledges on arrival, so the simulator's acknowledgement window never waits for it."""
    return matching(offered, min(MAX_DEPTH, max(1, sum(max(1, q.depth) for q in offered))))


@lru_cache(maxsize=None)
def channel_schema(type_name: str) -> foxglove.Schema | None:
    """The schema a bag stores for `pkg/msg/Type` (one text per type, however many robots); None without a .msg."""
    definition = message_definition(type_name)
    if definition.encoding != 'ros2msg':
        return None
    return foxglove.Schema(name=type_name, encoding=definition.encoding, data=definition.text.encode())


class ChannelClients:
    """The server's listener: each client's subscribe and unsubscribe, queued as (channel id, +1 / -1) for the
    node's thread. The SDK calls it from its own threads, and calls `on_unsubscribe` for every channel a client
    held when it disconnects or when the channel is withdrawn."""

    def __init__(self) -> None:
        self.changes: queue.SimpleQueue[tuple[int, int]] = queue.SimpleQueue()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.changes.put((channel.id, 1))

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self.changes.put((channel.id, -1))


@dataclass
class Forwarded:
    """One topic served as a channel, and its ROS subscription while a client reads it."""

    topic: str
    msg_type: type
    channel: foxglove.Channel
    clients: int = 0
    subscription: Subscription | None = None
    latched: bool = False


class FoxgloveBridge(Node):
    """Advertises the graph's topics on the server and forwards the ones its clients read."""

    def __init__(self, server: WebSocketServer, context: foxglove.Context, clients: ChannelClients) -> None:
        # No /rosout of its own: its log lines would be a topic it forwards to itself.
        super().__init__(NODE_NAME, enable_rosout=False, start_parameter_services=False)
        self._server = server
        self._foxglove_context = context
        self._listener = clients
        self._forwarded: dict[str, Forwarded] = {}
        self._by_channel: dict[int, Forwarded] = {}
        self._skipped: set[str] = set()
        self.time_ns = 0
        """The simulation's newest /clock tick: each message's log time, and the server's time."""
        self._sent_time_ns = 0   # nothing to send before the first tick
        self._sent_at = 0.0
        self.create_subscription(ClockMessage, CLOCK_TOPIC, self._on_clock, NEWEST_ONLY, raw=True)
        steady = Clock(clock_type=ClockType.STEADY_TIME)   # the graph and the clients, also while /clock stands
        self.create_timer(DISCOVERY_PERIOD, self._discover, clock=steady)
        self.create_timer(REQUEST_PERIOD, self._follow_clients, clock=steady)
        self._discover()

    def _on_clock(self, data: bytes) -> None:
        stamp = deserialize_message(data, ClockMessage).clock
        self.time_ns = nanoseconds_from_stamp(stamp.sec, stamp.nanosec)
        forwarded = self._forwarded.get(CLOCK_TOPIC)
        if forwarded is not None and forwarded.clients:
            forwarded.channel.log(data, log_time=self.time_ns)
        if time.monotonic() - self._sent_at >= TIME_PERIOD:
            self._broadcast_time()

    def _broadcast_time(self) -> None:
        self._server.broadcast_time(self.time_ns)
        self._sent_time_ns, self._sent_at = self.time_ns, time.monotonic()

    def _forward(self, forwarded: Forwarded, data: bytes) -> None:
        forwarded.channel.log(data, log_time=self.time_ns)

    def _discover(self) -> None:
        """Advertise new topics that have a publisher; withdraw those gone from the graph, and those we read whose
        publishers are all gone (our own subscription keeps a topic in the graph)."""
        graph = dict(self.get_topic_names_and_types())
        for topic, forwarded in list(self._forwarded.items()):
            reading = forwarded.subscription is not None or topic == CLOCK_TOPIC
            if topic not in graph or (reading and not self.count_publishers(topic)):
                self._withdraw(forwarded)
        for topic, types in graph.items():
            if topic in self._forwarded or topic in self._skipped or topic_or_service_is_hidden(topic):
                continue
            if self.count_publishers(topic):
                self._advertise(topic, types)

    def _advertise(self, topic: str, types: list[str]) -> None:
        if len(types) != 1:
            self._skip(topic, f'published with several types ({", ".join(types)})')
            return
        try:
            msg_type = message_class(types[0])
        except (ImportError, AttributeError, ValueError):
            self._skip(topic, f'type {types[0]} is not installed here')
            return
        schema = channel_schema(types[0])
        if schema is None:
            self._skip(topic, f'no message definition (.msg) of {types[0]} is installed here')
            return
        channel = foxglove.Channel(topic, message_encoding='cdr', schema=schema, context=self._foxglove_context)
        forwarded = Forwarded(topic, msg_type, channel)
        self._forwarded[topic] = self._by_channel[channel.id()] = forwarded

    def _skip(self, topic: str, reason: str) -> None:
        self._skipped.add(topic)
        self.get_logger().warning(f'not serving {topic}: {reason}')

    def _withdraw(self, forwarded: Forwarded) -> None:
        self._unsubscribe(forwarded)
        del self._forwarded[forwarded.topic], self._by_channel[forwarded.channel.id()]
        forwarded.channel.close()   # the SDK unadvertises it; its clients' on_unsubscribe find nothing here

    def _follow_clients(self) -> None:
        """Subscribe in ROS to what a client reads now, drop what none reads any more; send the newest time."""
        while True:
            try:
                channel_id, change = self._listener.changes.get_nowait()
            except queue.Empty:
                break
            forwarded = self._by_channel.get(channel_id)
            if forwarded is None:
                continue
            forwarded.clients = max(0, forwarded.clients + change)
            if forwarded.clients == 0:
                self._unsubscribe(forwarded)
            elif forwarded.subscription is None or (change > 0 and forwarded.latched):
                self._subscribe(forwarded)
        if self._sent_time_ns != self.time_ns:
            self._broadcast_time()

    def _subscribe(self, forwarded: Forwarded) -> None:
        """A new subscription (a latched topic's again: DDS replays its kept messages to the new reader)."""
        if forwarded.topic == CLOCK_TOPIC:   # always read, for the server's time
            return
        self._unsubscribe(forwarded)
        qos = reading_qos([info.qos_profile for info in self.get_publishers_info_by_topic(forwarded.topic)])
        forwarded.latched = qos.durability == DurabilityPolicy.TRANSIENT_LOCAL
        forwarded.subscription = self.create_subscription(forwarded.msg_type, forwarded.topic,
                                                          partial(self._forward, forwarded), qos, raw=True)

    def _unsubscribe(self, forwarded: Forwarded) -> None:
        if forwarded.subscription is not None:
            self.destroy_subscription(forwarded.subscription)
            forwarded.subscription = None


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    senses = ', '.join(SENSE_TOPICS.values())
    parser = argparse.ArgumentParser(
        prog='foxglove', formatter_class=argparse.RawDescriptionHelpFormatter,
        description='Serve the running simulation to Foxglove (the app or its web page), no ROS install needed on\n'
                    'the viewing side: a Foxglove WebSocket server with every topic on this ROS domain as a channel\n'
                    '(CDR, ros2msg schemas as in the bags), topics that appear later included; the simulation\'s\n'
                    '/clock as the server\'s time; robot_description and TF for the 3D panel, the camera as an image.\n'
                    'In Foxglove: Open connection, Foxglove WebSocket, ws://HOST:PORT; then import the layout\n'
                    'docs/foxglove_layout.json of the repository (3D, camera, plots of odometry and proximity).',
        epilog=f'A topic is read only while a Foxglove panel shows it: the simulator renders the camera and reads\n'
               f'the other senses ({senses}) only while someone reads them,\n'
               f'so a layout without an image panel costs no rendering. The bridge never makes the simulator wait\n'
               f'(ros2 topic echo\'s QoS, a history of at most {MAX_DEPTH}).\n'
               'Exit codes: 0 stopped (Ctrl-C), 2 bad arguments or the address cannot be served on (port taken).\n\n'
               'examples:\n'
               '  foxglove                       # ws://127.0.0.1:8765 on this ROS_DOMAIN_ID\n'
               '  foxglove --port 0              # any free port (printed)\n'
               '  bringup avoid --foxglove       # the same, started and stopped with the run')
    parser.add_argument('--port', type=int, default=DEFAULT_PORT,
                        help=f'TCP port to serve on (default {DEFAULT_PORT}; 0 = any free port, printed)')
    parser.add_argument('--host', default=DEFAULT_HOST,
                        help=f'address to serve on (default {DEFAULT_HOST}: this machine only; 0.0.0.0 lets any '
                             'machine that reaches this one watch the run)')
    return parser.parse_args(argv)


def start_server(host: str, port: int, context: foxglove.Context, clients: ChannelClients) -> WebSocketServer:
    """The server, or one line and exit code 2 when the address cannot be served on."""
    problem = address_error(host, port)
    if problem is None:
        try:
            return foxglove.start_server(name=SERVER_NAME, host=host, port=port, capabilities=[Capability.Time],
                                         server_listener=clients, context=context)
        except RuntimeError as error:   # taken meanwhile: the SDK's own words
            problem = str(error).removeprefix('FoxgloveError: ')
    refuse(f'foxglove: error: cannot serve on {host}:{port}: {problem}')


def main(args: list[str] | None = None) -> None:
    argv = sys.argv if args is None else args
    options = parse_arguments(remove_ros_args(args=argv)[1:])
    if foxglove is None:
        refuse("foxglove: error: the foxglove-sdk Python package is not installed (pip install 'foxglove-sdk>=0.30.3,"
               "<0.31')")
    context, clients = foxglove.Context(), ChannelClients()
    server = start_server(options.host, options.port, context, clients)   # before DDS: a refusal starts nothing
    use_package_profile()
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    node = FoxgloveBridge(server, context, clients)
    try:
        warn_if_not_fast_dds(node.get_logger())
        if not is_loopback(options.host):
            print(f'foxglove: warning: serving on {options.host}: any machine that reaches this one can watch the '
                  'run', file=sys.stderr, flush=True)
        print(f'foxglove: {websocket_url(options.host, server.port)} on ROS_DOMAIN_ID={node.context.get_domain_id()} '
              '(in Foxglove: Open connection, Foxglove WebSocket)', flush=True)
        spin_until_shutdown(node, executor_type=EventsExecutor)
    finally:
        server.stop()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
