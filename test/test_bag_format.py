"""Bags from our writer against the rosbag2 format: schema texts, QoS, metadata.yaml, and what
rosbags, mcap_ros2 and our own reader make of them — including a writer killed mid-recording.

The reference schema texts in test/data/ are rosbag2's algorithm applied to the Jazzy .msg files
(shared/reference/rosbag2-mcap.md §1c).
"""
from __future__ import annotations

import importlib.metadata
import math
import re
import signal
import struct
import subprocess
import sys
import textwrap
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
import yaml
from builtin_interfaces.msg import Time
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader
from sensor_msgs.msg import JointState, Range
from std_msgs.msg import String

from epuck_ros.bag import msgdefs
from epuck_ros.bag.cdr import CdrDecoder
from epuck_ros.bag.gaps import bag_gaps, find_gaps
from epuck_ros.bag.info import format_info
from epuck_ros.bag.qos import INFINITE_NS, QosProfile, profiles_to_yaml
from epuck_ros.bag.reader import Bag
from epuck_ros.bag.writer import BackgroundWriter, BagExistsError, BagWriter

DATA = Path(__file__).parent / 'data'
REFERENCES = {'nav_msgs/msg/Odometry': DATA / 'schema_nav_msgs_Odometry.ros2msg.txt',
              'sensor_msgs/msg/Range': DATA / 'schema_sensor_msgs_Range.ros2msg.txt'}
ODOMETRY_HASH = 'RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0'
_BLOCK = re.compile(r'\n={80}\nMSG: (\S+)\n')
LATCHED = QosProfile(depth=1, durability='transient_local')


def reference_blocks(path: Path) -> list[tuple[str | None, str]]:
    """A reference text cut into (MSG name, .msg text); the root block has no name."""
    parts = _BLOCK.split(path.read_text(encoding='utf-8'))
    return [(None, parts[0])] + list(zip(parts[1::2], parts[2::2]))


@pytest.mark.parametrize('type_name', sorted(REFERENCES))
def test_schema_text_is_rosbag2s_byte_for_byte(type_name, tmp_path, monkeypatch):
    """Given the .msg files the reference was built from, the text is identical to the byte."""
    package, _, name = type_name.split('/')
    for block_name, text in reference_blocks(REFERENCES[type_name]):
        block_package, block_type = (package, name) if block_name is None else block_name.split('/')
        msg_file = tmp_path / 'share' / block_package / 'msg' / f'{block_type}.msg'
        msg_file.parent.mkdir(parents=True, exist_ok=True)
        msg_file.write_bytes(text.encode('utf-8'))
    monkeypatch.setenv('AMENT_PREFIX_PATH', str(tmp_path))
    assert msgdefs.schema_text(type_name).encode('utf-8') == REFERENCES[type_name].read_bytes()


@pytest.mark.parametrize('type_name', sorted(REFERENCES))
def test_schema_text_from_installed_msg_files_has_the_reference_layout(type_name, monkeypatch):
    """Same blocks in the same order, each the installed .msg file (their comments may differ by release)."""
    monkeypatch.delenv('AMENT_PREFIX_PATH', raising=False)
    ours = _BLOCK.split(msgdefs.schema_text(type_name))
    expected_names = [name for name, _ in reference_blocks(REFERENCES[type_name])[1:]]
    assert ours[1::2] == expected_names
    package, _, name = type_name.split('/')
    for block_name, text in zip([f'{package}/{name}', *ours[1::2]], ours[0::2]):
        block_package, block_type = block_name.split('/')
        installed = Path(sys.prefix) / 'share' / block_package / 'msg' / f'{block_type}.msg'
        assert text == installed.read_text(encoding='utf-8')


def test_type_hash_and_unknown_types():
    assert msgdefs.type_hash('nav_msgs/msg/Odometry') == ODOMETRY_HASH
    unknown = msgdefs.message_definition('no_such_pkg/msg/Thing')
    assert (unknown.encoding, unknown.text, unknown.type_hash) == ('unknown', '', '')


def test_qos_yaml_is_v9_strings_with_infinite_durations():
    text = profiles_to_yaml([QosProfile(history='unknown', depth=0, durability='transient_local')])
    assert text.startswith('- history: unknown\n  depth: 0\n')
    (profile,) = yaml.safe_load(text)
    assert profile['durability'] == 'transient_local'
    assert profile['deadline'] == {'sec': 9223372036, 'nsec': 854775807}
    assert INFINITE_NS == 9223372036 * 10**9 + 854775807
    with pytest.raises(ValueError, match='reliability'):
        QosProfile(reliability='sometimes')


# --- round trips ------------------------------------------------------------------------------------------

def stamp(nanoseconds: int) -> Time:
    return Time(sec=nanoseconds // 10**9, nanosec=nanoseconds % 10**9)


def sample_messages() -> list[tuple[str, object, int]]:
    """(topic, message, log_time): a latched world, odometry, eight ranges and joint states per step."""
    messages = [('/world', String(data='arena: {size: [1.0, 1.0]}\n'), 10**9)]
    for step in range(40):
        t = 10**9 + step * 32_000_000
        odom = Odometry(child_frame_id='base_link')
        odom.header.stamp, odom.header.frame_id = stamp(t), 'odom'
        odom.pose.pose.position.x, odom.pose.pose.orientation.z = 0.001 * step, math.sin(0.01 * step)
        odom.pose.pose.orientation.w = math.cos(0.01 * step)
        odom.twist.twist.linear.x, odom.pose.covariance[35] = 0.0628, 1e-5
        messages.append(('/odom', odom, t))
        for i in range(8):
            ray = Range(radiation_type=Range.INFRARED, field_of_view=0.1, max_range=0.07,
                        range=math.inf if (step + i) % 5 else 0.01 * i)
            ray.header.stamp, ray.header.frame_id = stamp(t), f'ps{i}'
            messages.append(('/proximity', ray, t))
        messages.append(('/joint_states', JointState(
            name=['left_wheel_joint', 'right_wheel_joint'], position=[0.1 * step, 0.2 * step],
            velocity=[3.14, 3.14]), t))
    return messages


TYPES = {'/world': 'std_msgs/msg/String', '/odom': 'nav_msgs/msg/Odometry',
         '/proximity': 'sensor_msgs/msg/Range', '/joint_states': 'sensor_msgs/msg/JointState'}


DECODERS = {topic: CdrDecoder(name, msgdefs.schema_text(name)) for topic, name in TYPES.items()}


def cdr(topic: str, message: object) -> bytes:
    """The message's CDR bytes as DDS delivers them.

    rmw_fastrtps's rmw_serialize reports its size *estimate* as the length, so serialize_message can
    end in a few junk bytes (JointState does); rosbags checks lengths exactly, so cut them off.
    Padding bytes inside are not initialised either: serialise a message once and keep the bytes.
    """
    data = serialize_message(message)
    return data[:DECODERS[topic].size(data)]


def write_bag(path: Path, compression: str = 'none', chunk_size: int = 4096) -> list[tuple[str, object, int, bytes]]:
    """Write the sample messages; returns them as (topic, message, log_time, CDR bytes written)."""
    messages = [(topic, message, t, cdr(topic, message)) for topic, message, t in sample_messages()]
    writer = BagWriter(path, compression, chunk_size=chunk_size)
    for topic, type_name in TYPES.items():
        writer.add_topic(topic, type_name, [LATCHED if topic == '/world' else QosProfile()])
    for topic, _, log_time, data in messages:
        writer.write(topic, data, log_time, log_time + 5)
    writer.close()
    return messages


def same_values(ours: object, theirs: object, field_type: str = '') -> None:
    """Field by field, exactly; float32 fields as the float32 the wire carries."""
    if hasattr(ours, 'get_fields_and_field_types'):
        for name, sub_type in ours.get_fields_and_field_types().items():
            same_values(getattr(ours, name), getattr(theirs, name), sub_type)
    elif isinstance(ours, (list, tuple)) or hasattr(ours, 'tolist'):
        assert list(ours) == list(theirs)
    elif field_type == 'float':
        assert np.float32(ours) == np.float32(theirs)
    else:
        assert ours == theirs


@pytest.fixture(params=['none', 'zstd', 'lz4'])
def written(request, tmp_path):
    path = tmp_path / 'run'
    return path, write_bag(path, request.param), request.param


def test_rosbags_reads_folder_and_file_message_for_message(written):
    path, messages, _ = written
    for source in (path, path / 'run_0.mcap'):
        with AnyReader([source]) as reader:
            read = [(c.topic, reader.deserialize(raw, c.msgtype), t) for c, t, raw in reader.messages()]
        assert [(topic, t) for topic, _, t in read] == [(topic, t) for topic, _, t, _ in messages]
        for (_, ours, _, _), (_, theirs, _) in zip(messages, read):
            same_values(ours, theirs)


def test_mcap_ros2_decodes_message_for_message(written):
    path, messages, _ = written
    with open(path / 'run_0.mcap', 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == 'ros2'
        read = list(reader.iter_decoded_messages())
    assert [(c.topic, m.log_time, m.publish_time) for _, c, m, _ in read] == [
        (topic, t, t + 5) for topic, _, t, _ in messages]
    for (_, ours, _, _), (_, _, _, theirs) in zip(messages, read):
        same_values(ours, theirs)


def test_our_reader_returns_the_serialised_bytes_and_decodes_them(written):
    path, messages, _ = written
    with Bag(path) as bag:
        read = list(bag.messages())
        decoders = {t.name: CdrDecoder(t.type_name, t.schema_text) for t in bag.topics.values()}
    assert [(m.topic, m.data, m.log_time, m.publish_time) for m in read] == [
        (topic, data, t, t + 5) for topic, _, t, data in messages]
    odom = decoders['/odom'].decode(read[1].data)
    assert odom['pose']['pose']['position']['x'] == messages[1][1].pose.pose.position.x
    assert odom['header']['frame_id'] == 'odom' and odom['pose']['covariance'][35] == 1e-5
    joints = decoders['/joint_states'].flat(read[10].data)
    assert joints['name[1]'] == 'right_wheel_joint' and joints['velocity[0]'] == 3.14


def test_metadata_yaml_agrees_with_the_mcap_channels(written):
    path, messages, compression = written
    info = yaml.safe_load((path / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert (info['version'], info['storage_identifier'], info['relative_file_paths']) == (9, 'mcap', ['run_0.mcap'])
    assert info['message_count'] == len(messages) == info['files'][0]['message_count']
    assert info['starting_time']['nanoseconds_since_epoch'] == messages[0][2]
    assert info['duration']['nanoseconds'] == messages[-1][2] - messages[0][2]
    assert info['compression_format'] == ''  # chunk compression is inside the MCAP, not rosbag2's
    with open(path / 'run_0.mcap', 'rb') as stream:
        summary = make_reader(stream).get_summary()
    channels = {c.topic: c for c in summary.channels.values()}
    for entry in info['topics_with_message_count']:
        meta = entry['topic_metadata']
        channel = channels[meta['name']]
        assert meta['type'] == summary.schemas[channel.schema_id].name == TYPES[meta['name']]
        assert meta['offered_qos_profiles'] == yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert meta['type_description_hash'] == channel.metadata['topic_type_hash'] != ''
        assert entry['message_count'] == summary.statistics.channel_message_counts[channel.id] == sum(
            1 for topic, *_ in messages if topic == meta['name'])
    assert channels['/world'].metadata['offered_qos_profiles'].count('transient_local') == 1
    assert {c.compression for c in summary.chunk_indexes} == {'' if compression == 'none' else compression}


def test_rosbag2_metadata_record_is_written_at_open_and_close(tmp_path):
    write_bag(tmp_path / 'run')
    with open(tmp_path / 'run' / 'run_0.mcap', 'rb') as stream:
        records = [m for m in make_reader(stream).iter_metadata() if m.name == 'rosbag2']
    opened, closed = (yaml.safe_load(r.metadata['serialized_metadata']) for r in records)
    assert (opened['message_count'], opened['starting_time']['nanoseconds_since_epoch']) == (0, 2**63 - 1)
    assert closed['message_count'] == len(sample_messages()) and closed['ros_distro']


def test_an_existing_bag_is_never_overwritten(tmp_path):
    write_bag(tmp_path / 'run')
    with pytest.raises(BagExistsError, match='already exists'):
        BagWriter(tmp_path / 'run')


# --- a writer that never closes its bag -----------------------------------------------------------------

KILLED_WRITER = textwrap.dedent('''
    import sys, time
    from epuck_ros.bag.qos import QosProfile
    from epuck_ros.bag.writer import BackgroundWriter, BagWriter
    writer = BagWriter(sys.argv[1], sys.argv[2], chunk_size=2000)
    background = BackgroundWriter(writer, flush_period=0.1)
    background.add_topic('/data', 'std_msgs/msg/String', [QosProfile()])
    payload = bytes([0, 1, 0, 0, 4, 0, 0, 0]) + b'abc' + bytes(1)
    for i in range(int(sys.argv[3])):
        background.write('/data', payload, 1000 + i)
    assert background.flush(timeout=120)  # everything written is now in complete chunks
    print('written', flush=True)
    time.sleep(60)
''')


@pytest.mark.parametrize('compression', ['none', 'zstd'])
def test_a_killed_writer_leaves_its_complete_chunks_readable(tmp_path, compression):
    path, count = tmp_path / 'killed', 5000
    writer = subprocess.Popen([sys.executable, '-c', KILLED_WRITER, str(path), compression, str(count)],
                              stdout=subprocess.PIPE, text=True)
    try:
        assert writer.stdout.readline().strip() == 'written'
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    assert not (path / 'metadata.yaml').exists()
    with Bag(path) as bag:
        assert not bag.closed_properly
        assert bag.topics['/data'].message_count == count
        assert [m.log_time for m in bag.messages()] == list(range(1000, 1000 + count))
        assert 'not closed properly' in format_info(bag)


def test_a_cut_file_yields_exactly_the_chunks_before_the_cut(tmp_path):
    writer = BagWriter(tmp_path / 'run')
    writer.add_topic('/data', 'std_msgs/msg/String', [QosProfile()])
    sizes = []
    for first in (0, 100, 200):
        for i in range(first, first + 100):
            writer.write('/data', serialize_message(String(data=str(i))), i)
        writer.flush()  # one chunk per hundred messages
        sizes.append((tmp_path / 'run' / 'run_0.mcap').stat().st_size)
    writer.close()
    whole = (tmp_path / 'run' / 'run_0.mcap').read_bytes()
    # inside the second chunk; inside its message index (the chunk itself is whole); after it; after all
    for cut_at, complete in ((sizes[0] + 40, 100), (sizes[1] - 5, 200), (sizes[1] + 3, 200), (sizes[2], 300)):
        cut = tmp_path / f'cut{cut_at}.mcap'
        cut.write_bytes(whole[:cut_at])
        with Bag(cut) as bag:
            assert not bag.closed_properly
            assert bag.message_count == complete
            assert [m.log_time for m in bag.messages()] == list(range(complete))


def test_background_writer_reports_a_failure_on_close(tmp_path):
    background = BackgroundWriter(BagWriter(tmp_path / 'run'))
    background.write('/never_added', b'\x00\x01\x00\x00', 1)
    with pytest.raises(RuntimeError, match='never_added'):
        background.close()


# --- package.xml: rosdep must be able to resolve every key ---------------------------------------------------

def test_package_xml_names_only_rosdep_keys_that_exist_and_every_ros_import():
    """Each dependency is a ROS package or a key ros/rosdistro defines (test/data/rosdep_keys.txt, with its
    commit); mcap, zstandard and lz4, which have no key, come with mcap-ros2-support's pip requirements."""
    root = Path(__file__).parent.parent
    known = {line for line in (DATA / 'rosdep_keys.txt').read_text().splitlines() if line and line[0] != '#'}
    package = ElementTree.parse(root / 'package.xml').getroot()
    named = {element.text for element in package if element.tag.endswith('depend')}
    ros_packages = {name for name in named if (Path(sys.prefix) / 'share' / name / 'package.xml').is_file()}
    assert sorted(named - ros_packages - known) == []
    pip_requirements = {re.split(r'[<>=; ]', r)[0] for r in importlib.metadata.requires('mcap-ros2-support')}
    pip_requirements |= {re.split(r'[<>=; ]', r)[0] for r in importlib.metadata.requires('mcap')}
    assert 'mcap-ros2-support' in named and {'mcap', 'zstandard', 'lz4'} <= pip_requirements
    imported = set()
    for source in (root / 'epuck_ros').rglob('*.py'):
        imported |= set(re.findall(r'^(?:from|import) (\w+_(?:msgs|srvs|interfaces)|rclpy)\b', source.read_text(),
                                   re.MULTILINE))
    assert sorted(imported - named) == []


# --- bag info: encodings, empty bags, stamp gaps, a summary that fails its CRC -------------------------------

def test_info_gives_each_channel_its_own_message_encoding(tmp_path):
    from mcap.writer import Writer
    with open(tmp_path / 'mixed.mcap', 'wb') as stream:
        writer = Writer(stream)
        writer.start(profile='ros2', library='test')
        json_schema = writer.register_schema('Pose', 'jsonschema', b'{"type": "object"}')
        cdr_schema = writer.register_schema('std_msgs/msg/String', 'ros2msg', b'string data\n')
        channels = {'/json': writer.register_channel('/json', 'json', json_schema),
                    '/schemaless': writer.register_channel('/schemaless', 'json', 0),
                    '/chatter': writer.register_channel('/chatter', 'cdr', cdr_schema)}
        for topic, channel in channels.items():
            data = serialize_message(String(data='hi')) if topic == '/chatter' else b'{"x": 1}'
            writer.add_message(channel, 5, data, 5)
        writer.finish()
    with Bag(tmp_path / 'mixed.mcap') as bag:
        info = format_info(bag)
        assert bag.topics_of_type('Pose') == []  # not CDR: never handed to the CDR decoders
    assert 'Topic: /json | Type: Pose | Count: 1 | Serialization Format: json' in info
    assert 'Topic: /schemaless | Type:  | Count: 1 | Serialization Format: json' in info
    assert 'Topic: /chatter | Type: std_msgs/msg/String | Count: 1 | Serialization Format: cdr' in info


def test_info_of_an_empty_bag_has_no_start_or_end(tmp_path):
    writer = BagWriter(tmp_path / 'empty')
    writer.add_topic('/odom', 'nav_msgs/msg/Odometry', [QosProfile()])
    writer.close()
    with Bag(tmp_path / 'empty') as bag:
        info = format_info(bag)
    assert 'Start:             none (no messages)\nEnd:               none (no messages)\n' in info
    assert '2262' not in info and 'Messages:          0' in info


def test_info_lists_stamp_gaps_and_incomplete_steps(tmp_path):
    writer = BagWriter(tmp_path / 'lossy')
    writer.add_topic('/odom', 'nav_msgs/msg/Odometry', [QosProfile()])
    writer.add_topic('/proximity', 'sensor_msgs/msg/Range', [QosProfile()])
    writer.add_topic('/world', 'std_msgs/msg/String', [QosProfile()])
    topics = dict(sample_messages_by_topic())
    for step, (odom, rays) in enumerate(zip(topics['/odom'], topics['/proximity'])):
        t = 10**9 + step * 32_000_000
        if step not in (10, 11, 12):
            writer.write('/odom', cdr('/odom', odom), t)
        for i, ray in enumerate(rays):
            if not (step == 20 and i in (3, 5)):
                writer.write('/proximity', cdr('/proximity', ray), t)
    writer.write('/world', cdr('/world', String(data='{}')), 10**9)
    writer.close()
    with Bag(tmp_path / 'lossy') as bag:
        info = format_info(bag)
    assert ('Stamp gaps:        /odom: ~3 of 40 messages missing: 1 stamp gap (3 periods missing, longest 0.128 s) '
            '(usual period 0.032 s, 1 per stamp)\n') in info
    assert ('/proximity: ~2 of 320 messages missing: 1 stamp with fewer than 8 messages (usual period 0.032 s, '
            '8 per stamp)') in info


def test_info_lists_a_periodic_topic_that_ends_before_the_others(tmp_path):
    """A reader that stalled: its topic's stamps stop while the other periodic topics go on to the end."""
    writer = BagWriter(tmp_path / 'stalled')
    writer.add_topic('/odom', 'nav_msgs/msg/Odometry', [QosProfile()])
    writer.add_topic('/proximity', 'sensor_msgs/msg/Range', [QosProfile()])
    topics = dict(sample_messages_by_topic())
    for step, (odom, rays) in enumerate(zip(topics['/odom'], topics['/proximity'])):
        t = 10**9 + step * 32_000_000
        writer.write('/odom', cdr('/odom', odom), t)
        for ray in rays if step < 25 else ():
            writer.write('/proximity', cdr('/proximity', ray), t)
    writer.close()
    with Bag(tmp_path / 'stalled') as bag:
        info = format_info(bag)
    steps = len(topics['/odom'])
    assert (f'/proximity: ~{8 * (steps - 25)} of {8 * steps} messages missing: ends {steps - 25} periods before the '
            'other periodic topics (usual period 0.032 s, 8 per stamp)') in info, info
    assert '/odom:' not in info


def test_wall_clock_stamps_never_make_simulated_topics_miss_the_epoch(tmp_path):
    """The first `scripts/run.sh` of a new user printed "/clock: ~56109941978 of 56109943853 messages missing":
    `rosout` (wall clock, here on 32 ms multiples) became the end every simulated topic missed. Each clock is now
    judged on its own, log lines on the step grid are not a periodic topic, and a report is bounded by the bag."""
    from rcl_interfaces.msg import Log

    from epuck_ros.ros.serialized import exact_cdr
    period, epoch_steps = 32_000_000, 56_109_941_978
    writer = BagWriter(tmp_path / 'run')
    for topic, type_name in (('/odom', 'nav_msgs/msg/Odometry'), ('/rosout', 'rcl_interfaces/msg/Log'),
                             ('/wall_odom', 'nav_msgs/msg/Odometry')):
        writer.add_topic(topic, type_name, [QosProfile()])

    def stamped(msg, ns: int) -> bytes:
        stamp = msg.stamp if isinstance(msg, Log) else msg.header.stamp
        stamp.sec, stamp.nanosec = divmod(ns, 10**9)
        return exact_cdr(msg)

    for step in range(1, 1876):   # 60 simulated seconds
        writer.write('/odom', stamped(Odometry(), step * period), 10**18 + step * period)
    rng = np.random.default_rng(3)
    for step in np.cumsum(rng.integers(1, 200, 16)):   # log lines now and then, on the wall clock's step grid
        writer.write('/rosout', stamped(Log(msg='cruising'), int(epoch_steps + step) * period), 10**18)
    for step in range(300):   # a node without use_sim_time publishing on the wall clock, steadily
        writer.write('/wall_odom', stamped(Odometry(), int(epoch_steps + step) * period), 10**18)
    writer.close()
    with Bag(tmp_path / 'run') as bag:
        checked, gaps = bag_gaps(bag)
        info = format_info(bag)
    assert checked == ['/odom', '/wall_odom'] and gaps == [], info
    assert 'Stamp gaps:        none in the 2 periodic stamped and answer topics' in info, info


def sample_messages_by_topic() -> dict[str, list]:
    """The sample messages per topic; proximity grouped by step (8 rays)."""
    by_topic: dict[str, list] = {}
    for topic, message, _ in sample_messages():
        by_topic.setdefault(topic, []).append(message)
    rays = by_topic['/proximity']
    by_topic['/proximity'] = [rays[i:i + 8] for i in range(0, len(rays), 8)]
    return by_topic


def test_a_summary_that_fails_its_crc_is_not_believed(tmp_path):
    write_bag(tmp_path / 'run')
    path = tmp_path / 'run' / 'run_0.mcap'
    data = bytearray(path.read_bytes())
    with open(path, 'rb') as stream:
        summary = make_reader(stream).get_summary()
    total = summary.statistics.message_count
    statistics_at = bytes(data).rindex(struct.pack('<Q', total))  # the Statistics record's message count
    data[statistics_at:statistics_at + 8] = struct.pack('<Q', total + 1000)
    path.write_bytes(bytes(data))
    with Bag(tmp_path / 'run') as bag:
        assert bag.message_count == total == len(list(bag.messages()))
        assert 'run_0.mcap: summary section fails its CRC: counted from its complete chunks' in format_info(bag)


def test_stamp_gaps_hold_when_most_of_a_topic_is_lost_and_leave_event_topics_alone():
    period = 32_000_000
    steps = np.arange(2000) * period
    rng = np.random.default_rng(7)
    kept = steps[rng.random(2000) > 0.6]  # 60 % of the steps lost: the median step is no longer the period
    lossy = find_gaps('/odom', kept)
    missing_between_first_and_last = int((kept[-1] - kept[0]) // period) + 1 - len(kept)
    assert lossy.period_ns == period and lossy.missing_messages == missing_between_first_and_last
    jittered = np.sort(steps + rng.normal(0, 0.05 * period, 2000).astype(np.int64))
    assert find_gaps('/jittery', jittered).missing_messages == 0
    events = np.cumsum(rng.exponential(3 * period, 500)).astype(np.int64)  # like rosout: no period
    assert find_gaps('/rosout', events) is None


def test_stamp_gaps_of_two_clusters_of_steps():
    """Two short steps then ten long ones: the 10th percentile falls between them (it was NaN, a traceback).
    Stamps on 13 of the 1,002 periods spanned are not judged periodic (fewer than a tenth: events on the grid);
    the same steps with the long ones filled in to a tenth are, with the gaps counted."""
    assert find_gaps('/clustered', np.cumsum([0, 10, 10] + [1000] * 10)) is None
    gaps = find_gaps('/clustered', np.cumsum([0, 10, 10] + [10] * 100 + [1000] * 10))
    assert (gaps.period_ns, gaps.gaps, gaps.missing_steps) == (10, 10, 990)


def test_a_zero_filled_tail_ends_the_readable_part(tmp_path):
    """A crash can leave a file extended with zeros: they are not records (opcode 0), so reading stops there
    instead of walking them nine bytes at a time (a GB of zeros took minutes)."""
    write_bag(tmp_path / 'run')
    whole = (tmp_path / 'run' / 'run_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(whole[:len(whole) // 2])
    with Bag(cut) as bag:
        complete, ignored = bag.message_count, bag.files[0].ignored_bytes
    cut.write_bytes(whole[:len(whole) // 2] + bytes(1_000_000))
    with Bag(cut) as bag:
        assert bag.message_count == complete and complete > 0
        assert bag.files[0].ignored_bytes == ignored + 1_000_000
