"""QoS profiles as rosbag2 stores them (metadata v9): policy names as strings, durations as sec/nsec.

The same list goes into the channel's ``offered_qos_profiles`` (as a YAML string) and into
metadata.yaml (as a YAML list); rosbags matches the two and yields nothing if they differ,
so both are produced from one `QosProfile`. Plain Python: the recorder converts rclpy's
profiles into this, and the inspection tools never need ROS.
"""
from __future__ import annotations

from dataclasses import dataclass

import yaml

from epuck_ros.conversions import NS_PER_SECOND

INFINITE_NS = 9_223_372_036_854_775_807
"""RMW_DURATION_INFINITE, written as ``sec: 9223372036, nsec: 854775807``."""

HISTORY = ('system_default', 'keep_last', 'keep_all', 'unknown')
RELIABILITY = ('system_default', 'reliable', 'best_effort', 'unknown', 'best_available')
DURABILITY = ('system_default', 'transient_local', 'volatile', 'unknown', 'best_available')
LIVELINESS = ('system_default', 'automatic', 'manual_by_topic', 'unknown', 'best_available')


@dataclass(frozen=True)
class QosProfile:
    """One offered QoS profile; durations in nanoseconds."""

    history: str = 'keep_last'
    depth: int = 10
    reliability: str = 'reliable'
    durability: str = 'volatile'
    deadline_ns: int = INFINITE_NS
    lifespan_ns: int = INFINITE_NS
    liveliness: str = 'automatic'
    liveliness_lease_duration_ns: int = INFINITE_NS
    avoid_ros_namespace_conventions: bool = False

    def __post_init__(self) -> None:
        for name, allowed in (('history', HISTORY), ('reliability', RELIABILITY),
                              ('durability', DURABILITY), ('liveliness', LIVELINESS)):
            if getattr(self, name) not in allowed:
                raise ValueError(f'QoS {name} {getattr(self, name)!r} is not one of {", ".join(allowed)}')

    def to_dict(self) -> dict:
        """The v9 mapping, keys in rosbag2's order."""
        return {
            'history': self.history,
            'depth': self.depth,
            'reliability': self.reliability,
            'durability': self.durability,
            'deadline': _duration(self.deadline_ns),
            'lifespan': _duration(self.lifespan_ns),
            'liveliness': self.liveliness,
            'liveliness_lease_duration': _duration(self.liveliness_lease_duration_ns),
            'avoid_ros_namespace_conventions': self.avoid_ros_namespace_conventions,
        }


def _duration(nanoseconds: int) -> dict:
    nanoseconds = min(nanoseconds, INFINITE_NS)
    return {'sec': nanoseconds // NS_PER_SECOND, 'nsec': nanoseconds % NS_PER_SECOND}


class RosbagYamlDumper(yaml.SafeDumper):
    """Block style with indented sequences, as yaml-cpp writes rosbag2's files."""

    def increase_indent(self, flow: bool = False, indentless: bool = False) -> None:
        super().increase_indent(flow, False)


def dump_yaml(data: object) -> str:
    return yaml.dump(data, Dumper=RosbagYamlDumper, sort_keys=False, default_flow_style=False)


def profiles_to_yaml(profiles: list[QosProfile]) -> str:
    """The channel metadata string; '' for no profiles, as in rosbag2's own test bags."""
    if not profiles:
        return ''
    return dump_yaml([p.to_dict() for p in profiles]).rstrip('\n')
