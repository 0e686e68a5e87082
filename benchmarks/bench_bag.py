"""Bag writing and inspection speed: recorder throughput, and `info`/`summary` on a 1,000,000-message bag.

1. Writer alone: messages/s that `BagWriter` (and the recorder's `BackgroundWriter`) take, per compression.
2. Through DDS: the `record` executable in its own process while this process publishes the sim's traffic
   (12 messages per 32 ms step) at rising rates; messages recorded / published. The sim at 10x real time
   needs 3,750 msg/s.
3. A bag of >= 1,000,000 messages at the sim's rates (a 44-minute run: clock, odom, ground_truth, 8 ranges,
   joint_states per step) under /tmp; `bag info` (of which the stamp-gap check reading every stamp) and
   `bag summary` on it, in process and as commands, against rosbags' AnyReader deserialising the same topics
   of the same bag in the same run.

Run: python benchmarks/bench_bag.py [--messages N] [--skip-dds] [--keep]
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import signal
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState, Range

from epuck_ros.bag.cdr import CdrDecoder
from epuck_ros.bag.gaps import bag_gaps
from epuck_ros.bag.info import format_info
from epuck_ros.bag.msgdefs import schema_text
from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.reader import Bag
from epuck_ros.bag.run_summary import load_run, summarise
from epuck_ros.bag.writer import BackgroundWriter, BagWriter

STEP_NS = 32_000_000
MESSAGES_PER_STEP = 12
BIN = Path(sys.executable).parent
TOPICS = {'/clock': 'rosgraph_msgs/msg/Clock', '/odom': 'nav_msgs/msg/Odometry',
          '/ground_truth': 'nav_msgs/msg/Odometry', '/proximity': 'sensor_msgs/msg/Range',
          '/joint_states': 'sensor_msgs/msg/JointState'}
SUMMARY_TOPICS = ['/odom', '/ground_truth', '/proximity', '/world']
X_MARK, Y_MARK, QZ_MARK, QW_MARK, RANGE_MARK, ANGLE_MARK = 1234.5, 2345.5, 0.125, 0.375, 0.0625, 11.5


class Template:
    """One serialised message whose stamp and a few fields are overwritten in place for every step."""

    def __init__(self, message: object, type_name: str, marks: dict[str, tuple[str, float]]) -> None:
        data = serialize_message(message)
        self.data = bytearray(data[:CdrDecoder(type_name, schema_text(type_name)).size(data)])
        self.fields = {name: (code, bytes(self.data).index(struct.pack('<' + code, mark)))
                       for name, (code, mark) in marks.items()}

    def fill(self, stamp_ns: int, **values: float) -> bytearray:
        struct.pack_into('<iI', self.data, 4, *divmod(stamp_ns, 10**9))
        for name, value in values.items():
            code, offset = self.fields[name]
            struct.pack_into('<' + code, self.data, offset, value)
        return self.data


def templates() -> dict[str, Template]:
    odom = Odometry(child_frame_id='base_link')
    odom.header.frame_id = 'odom'
    odom.pose.pose.position.x, odom.pose.pose.position.y = X_MARK, Y_MARK
    odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = QZ_MARK, QW_MARK
    odom.pose.covariance = [1e-6 * (i % 7 == 0) for i in range(36)]
    pose_marks = {'x': ('d', X_MARK), 'y': ('d', Y_MARK), 'qz': ('d', QZ_MARK), 'qw': ('d', QW_MARK)}
    ray = Range(radiation_type=Range.INFRARED, field_of_view=0.1, max_range=0.07, range=RANGE_MARK)
    ray.header.frame_id = 'ps0'
    joints = JointState(name=['left_wheel_joint', 'right_wheel_joint'], position=[ANGLE_MARK, 0.0],
                        velocity=[1.88, 3.77])
    clock = Clock(clock=Time(sec=1, nanosec=2))
    return {'/clock': Template(clock, TOPICS['/clock'], {}),
            '/odom': Template(odom, TOPICS['/odom'], pose_marks),
            '/ground_truth': Template(odom, TOPICS['/ground_truth'], pose_marks),
            '/proximity': Template(ray, TOPICS['/proximity'], {'range': ('f', RANGE_MARK)}),
            '/joint_states': Template(joints, TOPICS['/joint_states'], {'angle': ('d', ANGLE_MARK)})}


def sim_traffic(steps: int) -> Iterator[tuple[str, bytearray, int]]:
    """(topic, CDR bytes, log_time) for `steps` steps of a robot circling at the course's 0.078 m radius."""
    parts = templates()
    radius, w = 0.078, 0.7246
    for step in range(1, steps + 1):
        t = step * STEP_NS
        angle = w * t * 1e-9
        pose = {'x': radius * math.sin(angle), 'y': radius * (1 - math.cos(angle)),
                'qz': math.sin(angle / 2), 'qw': math.cos(angle / 2)}
        yield '/clock', parts['/clock'].fill(t), t
        yield '/odom', parts['/odom'].fill(t, **pose), t
        yield '/ground_truth', parts['/ground_truth'].fill(t, **pose), t
        for i in range(8):
            near = 0.02 + 0.0004 * ((step + i) % 100) if (step + i) % 97 < 5 else math.inf
            parts['/proximity'].fill(t, range=near)[16:19] = f'ps{i}'.encode()
            yield '/proximity', parts['/proximity'].data, t
        yield '/joint_states', parts['/joint_states'].fill(t, angle=angle), t


def new_writer(path: Path, compression: str = 'none') -> BagWriter:
    writer = BagWriter(path, compression)
    for topic, type_name in TOPICS.items():
        writer.add_topic(topic, type_name, [QosProfile(history='unknown', depth=0)])
    return writer


def timed(action: Callable[[], object]) -> tuple[float, object]:
    begin = time.perf_counter()
    result = action()
    return time.perf_counter() - begin, result


def bench_writer(workdir: Path, steps: int = 10_000) -> None:
    traffic = [(topic, bytes(data), t) for topic, data, t in sim_traffic(steps)]
    print(f'\n1. Writer alone ({len(traffic):,} sim messages, held in memory)')
    for compression in ('none', 'zstd', 'lz4'):
        writer = new_writer(workdir / f'writer_{compression}', compression)
        seconds, _ = timed(lambda: [writer.write(*m) for m in traffic] and writer.close())
        print(f'   BagWriter {compression:<5}  {len(traffic) / seconds:>10,.0f} msg/s')
    background = BackgroundWriter(new_writer(workdir / 'background'))
    enqueue, _ = timed(lambda: [background.write(*m) for m in traffic])
    total, _ = timed(background.close)
    print(f'   BackgroundWriter: callbacks enqueue {len(traffic) / enqueue:,.0f} msg/s, '
          f'written {len(traffic) / (enqueue + total):,.0f} msg/s end to end')


def bench_dds(workdir: Path, rates: tuple[int, ...] = (3750, 7500, 15000), seconds: float = 2.0) -> None:
    """Recorded / published for the sim's traffic mix published by this process at each rate (msg/s)."""
    import rclpy
    from rclpy.qos import QoSProfile
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    print(f'\n2. Through DDS: record in its own process, {seconds:.0f} s of sim traffic per rate '
          f'(ROS_DOMAIN_ID={os.environ.get("ROS_DOMAIN_ID", "0")})')
    rclpy.init()
    node = rclpy.create_node('bench_bag_publisher')
    classes = {'/clock': Clock, '/odom': Odometry, '/ground_truth': Odometry, '/proximity': Range,
               '/joint_states': JointState}
    publishers = {t: node.create_publisher(c, t, QoSProfile(depth=16)) for t, c in classes.items()}
    try:
        for rate in rates:
            bag = workdir / f'dds_{rate}'
            log = workdir / f'record_{rate}.log'
            with open(log, 'w') as output:
                recorder = subprocess.Popen([str(BIN / 'record'), '-o', str(bag), *TOPICS],
                                            stdout=output, stderr=subprocess.STDOUT)
            while not all(p.get_subscription_count() for p in publishers.values()):
                time.sleep(0.05)
            time.sleep(1.0)  # DDS matching of every reader and writer
            steps = int(rate * seconds / MESSAGES_PER_STEP)
            begin = time.perf_counter()
            for index, (topic, data, _) in enumerate(sim_traffic(steps)):
                publishers[topic].publish(bytes(data))
                if index % MESSAGES_PER_STEP == MESSAGES_PER_STEP - 1:
                    delay = begin + (index + 1) / rate - time.perf_counter()
                    if delay > 0:
                        time.sleep(delay)
            achieved = steps * MESSAGES_PER_STEP / (time.perf_counter() - begin)
            time.sleep(1.5)
            recorder.send_signal(signal.SIGINT)
            recorder.wait(30)
            with Bag(bag) as recorded:
                count = recorded.message_count
            published = steps * MESSAGES_PER_STEP
            print(f'   {achieved:>8,.0f} msg/s published: {count:,} of {published:,} recorded '
                  f'({100 * count / published:.1f} %)')
            report = [line.split(']: ', 1)[-1] for line in log.read_text().splitlines() if 'lost' in line]
            print('\n'.join(f'      record says: {line}' for line in report))
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def bench_inspection(workdir: Path, messages: int) -> None:
    steps = -(-messages // MESSAGES_PER_STEP)
    path = workdir / 'million'
    writer = new_writer(path)
    seconds, _ = timed(lambda: [writer.write(*m) for m in sim_traffic(steps)] and writer.close())
    size = (path / 'million_0.mcap').stat().st_size
    total = steps * MESSAGES_PER_STEP
    print(f'\n3. A {total:,}-message bag ({size / 2**20:.0f} MiB, {steps * 0.032 / 60:.0f} simulated minutes): '
          f'generated and written in {seconds:.1f} s ({total / seconds:,.0f} msg/s incl. generation)')

    def info() -> str:
        with Bag(path) as bag:
            return format_info(bag)

    def summary() -> object:
        with Bag(path) as bag:
            return summarise(load_run(bag))

    def rosbags(deserialise: bool) -> int:
        from rosbags.highlevel import AnyReader
        count = 0
        with AnyReader([path]) as reader:
            wanted = [c for c in reader.connections if c.topic in SUMMARY_TOPICS]
            for connection, _, raw in reader.messages(connections=wanted):
                if deserialise:
                    reader.deserialize(raw, connection.msgtype)
                count += 1
        return count

    def gaps() -> object:
        with Bag(path) as bag:
            return bag_gaps(bag)

    info_s, _ = timed(info)
    gaps_s, (judged, missing) = timed(gaps)
    info_cli, _ = timed(lambda: subprocess.run([str(BIN / 'bag'), 'info', str(path)], check=True,
                                               capture_output=True))
    summary_s, result = timed(summary)
    summary_cli, _ = timed(lambda: subprocess.run([str(BIN / 'bag'), 'summary', str(path)], check=True,
                                                  capture_output=True))
    read_s, read = timed(lambda: rosbags(False))
    rosbags_s, decoded = timed(lambda: rosbags(True))
    print(f'   bag info     {info_s * 1000:8.1f} ms in process, {info_cli:.2f} s as a command (Python start-up '
          f'included); the stamp-gap check alone {gaps_s * 1000:.0f} ms for {len(judged)} topics '
          f'({len(missing)} with gaps)')
    print(f'   bag summary  {summary_s:8.2f} s  = {decoded / summary_s:>9,.0f} msg/s of the {decoded:,} messages '
          f'it reads ({summary_cli:.2f} s as a command); circle radius {result.circle.radius:.4f} m')
    print(f'   rosbags      {rosbags_s:8.2f} s  = {decoded / rosbags_s:>9,.0f} msg/s AnyReader + deserialize, '
          f'same topics ({read / read_s:,.0f} msg/s reading only)')
    print(f'   ratios: summary is {rosbags_s / summary_s:.1f}x faster than rosbags deserialising; '
          f'info answers in {info_s * 1000:.0f} ms, counts from the MCAP summary and every stamp read for gaps')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--messages', type=int, default=1_000_000, help='size of the inspection bag')
    parser.add_argument('--skip-dds', action='store_true', help='skip the recording-through-DDS part')
    parser.add_argument('--keep', action='store_true', help='keep the bags (printed folder under /tmp)')
    args = parser.parse_args()
    workdir = Path(tempfile.mkdtemp(prefix='epuck_bench_bag_'))
    try:
        bench_writer(workdir)
        if not args.skip_dds:
            bench_dds(workdir)
        bench_inspection(workdir, args.messages)
    finally:
        if args.keep:
            print(f'\nbags kept in {workdir}')
        else:
            shutil.rmtree(workdir)


if __name__ == '__main__':
    main()
