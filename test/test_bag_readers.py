"""Every message of a recorded run, on every topic the package publishes, is read by two readers nobody here wrote
(rosbags' AnyReader and mcap_ros2's decoder) and re-serialises to the very same bytes: exact CDR, zero padding.

Before the fix, the simulator's step messages were built from rclpy's `serialize_message`, whose buffer is longer
than the CDR and whose padding is stale memory: AnyReader refused the whole bag ("CDR message size mismatch for
sensor_msgs/msg/JointState")."""
from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader
from mcap_ros2._dynamic import serialize_dynamic
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from epuck_ros.bag.msgdefs import schema_text
from epuck_ros.ros.tf_ports import tf_available

BAGS = Path(__file__).resolve().parents[1] / 'bags'
FROM_RCL = ('/rosout', '/parameter_events')
"""Published by rcl itself for every node (through Fast DDS's own serializer, which leaves its alignment padding
as it finds it: seen non-zero): both readers must decode them, the byte-exact check is for the package's topics."""
STEP_TOPICS = ('odom', 'ground_truth', 'proximity', 'ir_raw', 'joint_states')
"""Per-robot topics the simulator publishes every step (as patched bytes)."""
RUN_STEPS = 63
"""Steps of a `--duration 2` run: t = 0.032 .. 2.016 s, the first step at or after 2 s ending it."""


def assert_same_cdr(written: bytes, recorded: bytes, what: str) -> None:
    """`recorded` is the CDR `written` by the reader's own encoder, to the byte; Fast DDS may pad a payload it sends
    (a transient-local String, seen on `world`) with up to 3 zero bytes to a multiple of 4, which CDR allows."""
    padding = recorded[len(written):]
    assert recorded[:len(written)] == written and padding == bytes(len(padding)) and len(padding) < 4, what


def assert_every_message_reads_back_exactly(bag: Path) -> dict[str, int]:
    """Count per topic, after checking each message with both readers; fails naming the topic and message."""
    typestore = get_typestore(Stores.ROS2_JAZZY)
    counts: dict[str, int] = {}
    with AnyReader([bag], default_typestore=typestore) as reader:
        for connection, _, rawdata in reader.messages():
            msg = reader.deserialize(rawdata, connection.msgtype)
            again = typestore.serialize_cdr(msg, connection.msgtype)
            if connection.topic not in FROM_RCL:
                assert_same_cdr(bytes(again), bytes(rawdata),
                                f'{connection.topic} message {counts.get(connection.topic, 0)}')
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
    (mcap_file,) = bag.glob('*.mcap')
    decoded: dict[str, int] = {}
    encoders = {}
    with open(mcap_file, 'rb') as stream:
        for schema, channel, message, ros_msg in make_reader(stream, decoder_factories=[DecoderFactory()]) \
                .iter_decoded_messages():
            if schema.name not in encoders:
                encoders[schema.name] = serialize_dynamic(schema.name, schema_text(schema.name))[schema.name]
            if channel.topic not in FROM_RCL:
                assert_same_cdr(encoders[schema.name](ros_msg), message.data, f'{channel.topic} (mcap_ros2)')
            decoded[channel.topic] = decoded.get(channel.topic, 0) + 1
    assert decoded == counts
    return counts


@pytest.mark.parametrize('robots', [1, 3])
def test_a_recorded_run_reads_back_exactly_with_rosbags_and_mcap_ros2(launch, tmp_path, robots):
    bag = tmp_path / 'run'
    run = launch('bringup', 'avoid', '--robots', str(robots), '--duration', '2', '--real-time-factor', '0',
                 '--seed', '5', '--record', str(bag))
    assert run.proc.wait(timeout=180) == 0, run.output()
    counts = assert_every_message_reads_back_exactly(bag)
    names = [''] if robots == 1 else [f'epuck{i}/' for i in range(robots)]
    for name in names:
        for topic in STEP_TOPICS:
            assert counts.get(f'/{name}{topic}', 0) >= RUN_STEPS, (topic, counts)
        if robots == 1:   # avoid's answers (patched bytes too): every command that drove a step, not the last's
            assert counts.get('/wheel_cmd', 0) >= RUN_STEPS - 1, counts
        assert counts.get(f'/{name}collisions', 0) >= 1, counts
        assert counts.get(f'/{name}robot_description', 0) == 1, counts
    if robots > 1:   # one avoid drives them all: its declaration, then one answer per step for every robot
        assert counts.get('/swarm/command', 0) >= RUN_STEPS, counts
    if tf_available():   # the run can be shown from the bag alone (Foxglove's 3D panel): the whole TF tree
        assert counts.get('/tf', 0) >= robots * RUN_STEPS and counts.get('/tf_static', 0) == 1, counts
    for topic in ('/clock', '/world', '/world_markers'):
        assert counts.get(topic, 0) >= 1, counts


@pytest.mark.parametrize('bag', sorted(path for path in BAGS.iterdir() if (path / 'metadata.yaml').exists()),
                         ids=lambda path: path.name)
def test_every_shipped_bag_reads_back_exactly(bag):
    assert sum(assert_every_message_reads_back_exactly(bag).values()) > 0
