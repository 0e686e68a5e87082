"""Step messages as CDR bytes (ros/serialized.py), checked against rclpy's own (de)serialisation, no DDS."""
import math
import struct

import pytest
from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, Range
from std_msgs.msg import Float64MultiArray, MultiArrayDimension, MultiArrayLayout

from epuck_ros.bag.msgdefs import schema_text
from epuck_ros.conversions import stamp_label
from epuck_ros.ros.serialized import Patch, array_bytes, array_values, exact_cdr


def test_a_patched_message_is_the_exact_cdr_of_the_message_with_those_values():
    msg = Odometry()
    msg.header.frame_id = 'epuck3/odom'
    patch = Patch(msg, [('header.stamp.sec', 'i'), ('header.stamp.nanosec', 'I'), ('pose.pose.position.x', 'd'),
                        ('twist.twist.angular.z', 'd')])
    data = patch.bytes((12, 345_000_000, -0.25, 1.5))
    msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345_000_000
    msg.pose.pose.position.x, msg.twist.twist.angular.z = -0.25, 1.5
    assert deserialize_message(data, Odometry) == msg
    assert data == exact_cdr(msg)
    # header 4 + stamp 8 + frame_id 4 + 12 + child_frame_id 4 + 1: 3 bytes of padding align the pose's doubles
    assert data[33:36] == bytes(3), 'the padding before the pose is zero (rclpy leaves it stale)'


def test_a_patch_like_another_patches_elements_of_sequences_and_the_other_messages_strings():
    def joints(prefix: str) -> JointState:
        return JointState(name=[prefix + 'left', prefix + 'right'], position=[0.0, 0.0])

    fields = [('header.stamp.sec', 'i'), ('position[1]', 'd')]
    patch = Patch(joints('epuck1/'), fields)
    other = joints('epuck2/')
    data = patch.like(other).bytes((7, 0.5))
    other.header.stamp.sec, other.position[1] = 7, 0.5
    assert deserialize_message(data, JointState) == other and data == exact_cdr(other)
    with pytest.raises(ValueError, match='not laid out'):   # position[1] lies further on
        patch.like(joints('a_much_longer_name/'))
    patch = Patch(MultiArrayLayout(dim=[MultiArrayDimension(label='a'), MultiArrayDimension(label='b')]),
                  [('dim[1].size', 'I')])
    assert deserialize_message(patch.bytes((9,)), MultiArrayLayout).dim[1].size == 9   # an element's field


def test_exact_cdr_is_what_an_independent_encoder_writes_and_not_longer_than_the_cdr():
    """The serialize_message of rclpy gave 132 bytes for this JointState; its CDR is 128 (as mcap_ros2 encodes)."""
    joints = JointState(name=['left_wheel_joint', 'right_wheel_joint'], position=[0.5, -1.0], velocity=[1.0, 0.0])
    joints.header.frame_id = 'base_link'
    for msg in (joints, Range(radiation_type=Range.INFRARED, range=0.25), Odometry(), Clock(),
                Float64MultiArray(data=[1.0, 2.0, 3.0])):
        name = f'{type(msg).__module__.split(".")[0]}/msg/{type(msg).__name__}'
        data = exact_cdr(msg)
        assert deserialize_message(data, type(msg)) == msg
        decoded = generate_dynamic(name, schema_text(name))[name](data)
        assert serialize_dynamic(name, schema_text(name))[name](decoded) == data, name
    assert len(exact_cdr(joints)) == 128 < len(serialize_message(joints))


@pytest.mark.parametrize('values', [[], [1.5], [0.0, -6.28], [float(i) / 3 for i in range(8)], [math.inf, 2.0]])
def test_array_values_reads_what_rclpy_serialised(values):
    assert array_values(serialize_message(Float64MultiArray(data=values))) == (tuple(values), None)


def test_array_values_of_a_nan_command_is_nan_for_the_simulator_to_refuse():
    (left, right), _ = array_values(serialize_message(Float64MultiArray(data=[math.nan, 1.0])))
    assert math.isnan(left) and right == 1.0


def test_an_array_with_a_layout_is_read_too():
    layout = MultiArrayLayout(dim=[MultiArrayDimension(label='wheels', size=2, stride=2)], data_offset=0)
    assert array_values(serialize_message(Float64MultiArray(layout=layout, data=[4.0, 5.0]))) == ((4.0, 5.0), None)


def _cdr(kind: int, order: str, dims: list[tuple[bytes, int, int]], values: list[float]) -> bytes:
    """A Float64MultiArray written by hand in CDR `kind` (XCDR1 0/1, XCDR2 plain 6/7: 8-byte values 4-aligned)."""
    body = bytearray(struct.pack(order + 'I', len(dims)))
    for label, size, stride in dims:
        body += struct.pack(order + 'I', len(label) + 1) + label + b'\0'
        body += bytes(-len(body) % 4) + struct.pack(order + '2I', size, stride)
    body += bytes(-len(body) % 4) + struct.pack(order + '2I', 0, len(values))
    body += bytes(-len(body) % (8 if kind < 6 else 4)) + struct.pack(f'{order}{len(values)}d', *values)
    return bytes((0, kind, 0, 0)) + bytes(body)


@pytest.mark.parametrize('kind, order', [(0, '>'), (1, '<')])
@pytest.mark.parametrize('dims', [[], [(b'wheels', 2, 2)], [(b'ab', 1, 2), (b'abcdefg', 3, 4)]])
def test_array_values_reads_xcdr1_either_way_round_as_rclpy_does(kind, order, dims):
    data = _cdr(kind, order, dims, [4.0, -5.5])
    assert array_values(data)[0] == tuple(deserialize_message(data, Float64MultiArray).data) == (4.0, -5.5)


@pytest.mark.parametrize('kind, order', [(6, '>'), (7, '<')])
def test_xcdr2_which_no_jazzy_middleware_sends_for_this_type_is_refused_quietly(kind, order, capfd):
    assert array_values(_cdr(kind, order, [], [4.0, -5.5])) is None
    assert capfd.readouterr() == ('', '')


def _malformed() -> dict[str, bytes]:
    good = serialize_message(Float64MultiArray(data=[1.0, 2.0]))
    too_many = bytearray(good)
    too_many[12:16] = (1000).to_bytes(4, 'little')   # claims 1,000 numbers: neither read past the end nor decoded
    with_dims = _cdr(1, '<', [(b'wheels', 2, 2)], [1.0, 2.0])
    huge_label = bytearray(with_dims)
    huge_label[8:12] = (2 ** 31).to_bytes(4, 'little')
    return {'too many numbers': bytes(too_many), 'big-endian, cut short': _cdr(0, '>', [], [1.0])[:-1],
            'huge label': bytes(huge_label), 'half a header': b'\x00\x01\x00', 'empty': b'',
            'huge counts': b'\x00\x01\x00\x00' + b'\xff' * 12, 'no CDR': b'\x12\x34' + good[2:],
            'XCDR2 parameter list': b'\x00\x0b' + good[2:]}


@pytest.mark.parametrize('data', _malformed().values(), ids=_malformed().keys())
def test_bytes_that_are_no_float64_array_read_as_none_without_a_word_from_rclpy(data, capfd):
    assert array_values(data) is None
    assert capfd.readouterr() == ('', '')   # rclpy's C deserialiser printed a line per message


def test_every_truncation_of_an_array_reads_as_none():
    data = _cdr(1, '<', [(b'wheels', 2, 2)], [1.0, 2.0])
    assert all(array_values(data[:end]) is None for end in range(len(data)))


@pytest.mark.parametrize('values', [[], [0.5], [float(i) / 3 for i in range(8)], [1.0, 2.0, 3.0]])
@pytest.mark.parametrize('stamp', [None, (0, 0), (12, 32_000_000), (1234567, 999_999_999)])
def test_array_bytes_is_the_exact_cdr_and_array_values_reads_back_the_numbers_and_the_step(values, stamp):
    msg = Float64MultiArray(data=values)
    if stamp is not None:
        msg.layout.dim = [MultiArrayDimension(label=stamp_label(*stamp), size=len(values), stride=len(values))]
    data = array_bytes(values, stamp)
    assert data == exact_cdr(msg)
    assert deserialize_message(data, Float64MultiArray) == msg
    assert array_values(data) == (tuple(values), stamp)


@pytest.mark.parametrize('label', [b'wheels', b'stamp=12', b'stamp=1.5', b'stamp=x.000000000', b'\xff\xfe',
                                   'stamp=\u00b2.000000000'.encode(), ('stamp=1.' + '\u00b2' * 9).encode(),
                                   'stamp=\u0663.032000000'.encode(), b'stamp=1' + b'0' * 400 + b'.000000000',
                                   b'stamp=2147483648.000000000', b'stamp=.000000000', b'stamp=+1.000000000'])
def test_an_array_whose_label_names_no_step_reads_with_no_stamp(label):
    assert array_values(_cdr(1, '<', [(label, 2, 2)], [1.0, 2.0])) == ((1.0, 2.0), None)


def test_the_latest_stamp_an_int32_holds_is_read():
    assert array_values(_cdr(1, '<', [(b'stamp=2147483647.999999999', 2, 2)], [1.0, 2.0])) == \
        ((1.0, 2.0), (2147483647, 999999999))


def test_every_truncation_of_a_stamped_array_reads_as_none():
    data = array_bytes([1.0, 2.0], (3, 64_000_000))
    assert all(array_values(data[:end]) is None for end in range(len(data)))
