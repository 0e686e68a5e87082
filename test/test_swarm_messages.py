"""The swarm messages (swarm_messages.py) as bytes (without DDS), and what the simulator does with bad ones (over
DDS). A swarm controller's declaration is a lockstep declaration of its robots (test_lockstep)."""
from __future__ import annotations

import numpy as np
import pytest
from conftest import ros_args
from nav_msgs.msg import Odometry
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray

from epuck_ros.swarm_messages import COMMAND_FIELDS, OBSERVATION_FIELDS, SwarmLayout, SwarmReader

FLOAT64_ARRAY = 'std_msgs/msg/Float64MultiArray'
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


@pytest.mark.parametrize('stamp', [(12, 32000000), (0, 0), None])
@pytest.mark.parametrize('fields', [COMMAND_FIELDS, OBSERVATION_FIELDS, ()])
@pytest.mark.parametrize('robots', [['epuck0'], ['a', 'bb', 'epuck10']])
def test_a_swarm_message_is_a_float64_multi_array_as_rosbags_writes_it(stamp, fields, robots):
    """Byte for byte what rosbags (and Fast DDS, zero padding) make of the same message, so bags, `ros2 topic echo`
    and Foxglove read it; and read back by `SwarmReader`."""
    data = np.arange(len(robots) * len(fields), dtype=float).reshape(len(robots), len(fields)) * 1.5 - 2.0
    raw = SwarmLayout(robots, fields).to_bytes(data, stamp)
    msg = TYPESTORE.deserialize_cdr(raw, FLOAT64_ARRAY)
    assert bytes(TYPESTORE.serialize_cdr(msg, FLOAT64_ARRAY)) == raw
    labels = [dim.label for dim in msg.layout.dim]
    assert labels[-2:] == ['robots=' + ','.join(robots), 'fields=' + ','.join(fields)]
    assert labels[:-2] == ([] if stamp is None else [f'stamp={stamp[0]}.{stamp[1]:09d}'])
    assert (msg.data == data.ravel()).all()
    read = SwarmReader().read(raw)
    assert (read.stamp, read.robots, read.fields) == (stamp, tuple(robots), tuple(fields))
    assert (read.data == data).all()


def test_bytes_that_are_no_swarm_message_are_none_not_an_error():
    good = SwarmLayout(['epuck0', 'epuck1'], COMMAND_FIELDS).to_bytes(np.ones((2, 2)), (1, 0))
    reader = SwarmReader()
    wrong_sizes = SwarmLayout(['epuck0'], COMMAND_FIELDS).to_bytes(np.ones((1, 2)), (1, 0)).replace(
        b'robots=epuck0', b'robots=epuckX,y')
    for bad in [b'', b'\x00\x01\x00\x00', good[:-8], good[:40], b'\x01' * 200, good.replace(b'stamp=1.', b'stamp=x.'),
                wrong_sizes, TYPESTORE.serialize_cdr(TYPESTORE.types[FLOAT64_ARRAY](
                    layout=TYPESTORE.types['std_msgs/msg/MultiArrayLayout'](dim=[], data_offset=0),
                    data=np.ones(3)), FLOAT64_ARRAY)]:
        assert reader.read(bytes(bad)) is None
    assert reader.read(good).robots == ('epuck0', 'epuck1')


def test_bad_swarm_commands_are_refused_in_a_line_and_good_ones_drive(launch, test_node):
    """Any bytes on `swarm/command` (not a swarm array, an unknown or twice-named robot, NaN): one throttled warning,
    the simulation goes on; then a good command (naming no step) drives the robots it names, and only those."""
    log = test_node.watch_log()
    sim = launch('sim', *ros_args({'robots': 3, 'noise': False, 'real_time_factor': 5.0}))
    test_node.wait_for_simulator()
    clocks = test_node.collect(Clock, '/clock', 100)
    truth = {name: test_node.collect(Odometry, f'/{name}/ground_truth') for name in ('epuck0', 'epuck1', 'epuck2')}
    pub = test_node.node.create_publisher(Float64MultiArray, '/swarm/command', QoSProfile(
        depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    test_node.spin_until(lambda: clocks and pub.get_subscription_count() > 0, what='the simulator')
    two = SwarmLayout(['epuck0', 'epuck2'], COMMAND_FIELDS)
    for bad, said in [(b'\x00\x01\x00\x00' + b'\xff' * 40, 'no swarm array'),
                      (SwarmLayout(['epuck0', 'nobody'], COMMAND_FIELDS).to_bytes(np.ones((2, 2)), None),
                       "no robot 'nobody'"),
                      (SwarmLayout(['epuck1', 'epuck1'], COMMAND_FIELDS).to_bytes(np.ones((2, 2)), None), 'twice'),
                      (SwarmLayout(['epuck0'], ('left',)).to_bytes(np.ones((1, 1)), None), 'fields left'),
                      (two.to_bytes(np.array([[np.nan, 1.0], [1.0, 1.0]]), None), 'finite')]:
        pub.publish(bad)
        test_node.wait_for_log(log, said, timeout=30.0)
        test_node.spin_for(1.1)   # the warnings are throttled to one a second (WARN_PERIOD)
    assert sim.proc.poll() is None
    pub.publish(two.to_bytes(np.array([[3.0, 3.0], [3.0, 3.0]]), None))
    test_node.spin_until(lambda: truth['epuck0'] and truth['epuck0'][-1].twist.twist.linear.x > 0.05 and
                         truth['epuck2'] and truth['epuck2'][-1].twist.twist.linear.x > 0.05, timeout=30.0,
                         what='epuck0 and epuck2 to drive')
    assert all(msg.twist.twist.linear.x == 0.0 for msg in truth['epuck1'])
    assert sim.proc.poll() is None
