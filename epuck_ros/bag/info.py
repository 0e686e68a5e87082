"""``bag info``: what ``ros2 bag info`` prints (rosbag2_py ``format_bag_metadata``), plus topic rates.

The counts and times come from the MCAP summary; a bag that was not closed properly is said to
be so, and its complete chunks are counted. Each channel's serialization format is the one the
file gives it (``cdr``, ``json``...). ``Stamp gaps`` reads the stamp of every message of the
stamped topics, and the step every lockstep answer (`wheel_cmd`, stamped `cmd_vel`) names against the bag's `/clock`
(`epuck_ros.bag.gaps`), and lists the topics where messages seem to be missing.
An empty bag has no start or end, so none is printed (rosbag2 prints INT64_MAX, Apr 2262).
"""
from __future__ import annotations

import time

from epuck_ros.bag.gaps import bag_gaps
from epuck_ros.bag.reader import Bag
from epuck_ros.conversions import NS_PER_SECOND

LABEL_WIDTH = 19


def format_size(size: int) -> str:
    """rosbag2's format_file_size: B without decimals, then KiB, MiB... with one."""
    units = ('B', 'KiB', 'MiB', 'GiB', 'TiB')
    value, index = float(size), 0
    while value >= 1024 and index < len(units) - 1:
        value /= 1024
        index += 1
    return f'{value:.0f} {units[0]}' if index == 0 else f'{value:.1f} {units[index]}'


def format_duration(nanoseconds: int) -> str:
    return f'{nanoseconds // NS_PER_SECOND}.{nanoseconds % NS_PER_SECOND:09d}s'


def format_time(nanoseconds: int) -> str:
    """``Jun 10 2026 11:42:53.307379851 (1781059373.307379851)`` in local time, as rosbag2 prints it."""
    seconds, rest = divmod(nanoseconds, NS_PER_SECOND)
    local = time.strftime('%b %e %Y %H:%M:%S', time.localtime(seconds))
    return f'{local}.{rest:09d} ({seconds}.{rest:09d})'


def _lines(label: str, values: list[str]) -> list[str]:
    """The first value after the padded label, the others indented to the same column."""
    head = f'{label + ":":<{LABEL_WIDTH}}'
    return [head + (values[0] if values else '')] + [' ' * LABEL_WIDTH + v for v in values[1:]]


def format_info(bag: Bag) -> str:
    topics = sorted(bag.topics.values(), key=lambda t: t.name)
    start = bag.start_ns
    duration = bag.end_ns - bag.start_ns if bag.start_ns is not None else 0
    distro = next((f.rosbag2_metadata.get('ros_distro') for f in bag.files if f.rosbag2_metadata), None)
    topic_lines = []
    for topic in topics:
        rate = topic.frequency
        topic_lines.append(
            f'Topic: {topic.name} | Type: {topic.type_name} | Count: {topic.message_count} | '
            f'Serialization Format: {topic.message_encoding}' + (f' | Rate: {rate:.2f} Hz' if rate is not None else ''))
    lines = ['']
    lines += _lines('Files', [f.path.name for f in bag.files])
    lines += _lines('Bag size', [format_size(bag.size)])
    lines += _lines('Storage id', ['mcap'])
    lines += _lines('ROS Distro', [distro or 'unknown'])
    for file in bag.files:
        if file.summary_problem:
            lines += _lines('Warning', [f'{file.path.name}: {file.summary_problem}: counted from its complete '
                                        f'chunks, {file.ignored_bytes} trailing bytes ignored'])
        elif not file.closed_properly:
            lines += _lines('Warning', [f'{file.path.name} was not closed properly (no summary): counted from '
                                        f'its complete chunks, {file.ignored_bytes} trailing bytes ignored'])
        if file.profile != 'ros2':
            lines += _lines('Warning', [f'{file.path.name} has MCAP profile {file.profile!r}, not ros2'])
    lines += _lines('Duration', [format_duration(duration)])
    lines += _lines('Start', [format_time(start) if start is not None else 'none (no messages)'])
    lines += _lines('End', [format_time(start + duration) if start is not None else 'none (no messages)'])
    lines += _lines('Messages', [str(bag.message_count)])
    lines += _lines('Topic information', topic_lines)
    checked, gaps = bag_gaps(bag)
    lines += _lines('Stamp gaps', [g.describe() for g in gaps] or
                    [f'none in the {len(checked)} periodic stamped and answer topics' if checked else
                     'no periodic stamped or answer topic'])
    lines += _lines('Service', ['0'])
    lines.append('Service information: ')
    return '\n'.join(lines)
