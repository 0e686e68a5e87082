"""A sense watched for a while during a recorded run is "not asked for" outside that while, not "lost" (issue 33,
item 9: a camera watched for 3 s in Foxglove made the recorder warn `lost: /camera/image_raw: ~244 of 435 messages
missing` and `bag info` list stamp gaps). The simulator says on each robot's latched `senses_on` which sense topics
it publishes from which step on; the recorder's loss report and `bag info` count a step without a message as missing
only while its sense was on."""
from __future__ import annotations

import pytest
from sensor_msgs.msg import Image
from test_bag_answers import copy_without

from epuck_ros.bag.gaps import bag_gaps, senses_on
from epuck_ros.bag.info import format_info
from epuck_ros.bag.reader import Bag
from epuck_ros.bag.steps import senses_on_from_text, senses_on_text


def test_the_senses_on_text_reads_back():
    text = senses_on_text((1, 24_000_000), ['camera/image_raw', 'camera/camera_info'])
    assert text == 'from the step after 1.024000000: camera/image_raw, camera/camera_info'
    assert senses_on_from_text(text) == (1_024_000_000, ['camera/image_raw', 'camera/camera_info'])
    assert senses_on_from_text(senses_on_text((0, 0), [])) == (0, [])
    assert senses_on_from_text('from the step after ².000000000: imu') is None


@pytest.fixture
def watched(launch, test_node, tmp_path):
    """`bringup forward --record` with a camera watched by the test's node from t >= 1 s until 20 images came: the
    bag."""
    from rosgraph_msgs.msg import Clock
    from rclpy.qos import ReliabilityPolicy, QoSProfile
    bag = tmp_path / 'watched'
    run = launch('bringup', 'forward', '--duration', '6', '--real-time-factor', '1', '--record', str(bag))
    clocks = test_node.collect(Clock, '/clock')
    test_node.spin_until(lambda: any(tick.clock.sec >= 1 for tick in clocks), 120, '/clock past 1 s')
    images: list = []
    subscription = test_node.node.create_subscription(
        Image, '/camera/image_raw', images.append, QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    test_node.spin_until(lambda: len(images) >= 20, 60, '20 camera images')
    test_node.node.destroy_subscription(subscription)
    assert run.proc.wait(timeout=120) == 0, run.output()
    assert 'lost: /camera' not in run.output() and 'no message lost' in run.output(), run.output()
    return bag


def test_a_sense_watched_for_a_while_is_not_reported_lost_and_a_loss_while_it_was_on_is(watched, tmp_path):
    """One recorded run (six real-time seconds) for both: the bag as recorded, then a copy of it with three images
    taken out while the camera was on."""
    with Bag(watched) as bag:
        assert 20 <= bag.topics['/camera/image_raw'].message_count < 150   # 188 steps; watched for some of them
        changes = senses_on(bag)['/camera/image_raw']
        _, gaps = bag_gaps(bag)
        info = format_info(bag)
    assert [published for _, published in changes] == [True, False], changes
    assert gaps == [], [g.describe() for g in gaps]
    assert 'Stamp gaps:        none in the' in info, info
    lossy = tmp_path / 'lossy'
    copy_without(watched, lossy, '/camera/image_raw', {10, 11, 12})
    with Bag(lossy) as bag:
        _, gaps = bag_gaps(bag)
    (camera,) = [g for g in gaps if g.topic == '/camera/image_raw']
    assert (camera.gaps, camera.missing_steps, camera.missing_at_end) == (1, 3, 0), camera.describe()
