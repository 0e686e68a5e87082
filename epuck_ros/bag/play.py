"""Replaying a bag, the part that needs no ROS: when each message is due, and with which QoS.

`PlaybackClock` maps wall time to bag time and back: a message logged at `t` is due `(t - start) / rate`
wall seconds after playback began, plus the time spent paused. The `bag_player` node
(`epuck_ros.nodes.play_node`) publishes each message when it is due and /clock from the same clock.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

from epuck_ros import untrusted_yaml
from epuck_ros.bag.qos import QosProfile

PLAY_DEPTH = 1000
"""History of every replayed topic: a burst (eight Range messages per step, at a high rate) must never
overwrite messages a reliable subscriber has not acknowledged yet."""
QOS_YAML_DEPTH = 8
"""Deepest nesting accepted in a channel's recorded QoS profiles (rosbag2 writes 3 levels)."""
CLOCK_TOPIC = '/clock'
"""Not replayed from the bag: the player publishes /clock itself, from the log time."""


class PlaybackClock:
    """Bag time (ns) at a wall instant (monotonic s) and the reverse, at `rate`, with pauses.

    Anchored at one (wall, bag) pair; pausing freezes bag time, resuming re-anchors it at the resume instant.
    """

    def __init__(self, start_ns: int, rate: float, now: float, paused: bool = False) -> None:
        if not (rate > 0.0 and math.isfinite(rate)):
            raise ValueError(f'rate must be positive and finite, got {rate}')
        self.rate = rate
        self._anchor_ns = start_ns
        self._anchor_wall = now
        self.paused = paused

    def bag_time(self, now: float) -> int:
        """The bag's log time being played at wall instant `now`."""
        if self.paused:
            return self._anchor_ns
        return self._anchor_ns + round((now - self._anchor_wall) * self.rate * 1e9)

    def due(self, log_time_ns: int) -> float:
        """When a message logged at `log_time_ns` is due, on the wall clock (inf while paused)."""
        if self.paused:
            return math.inf
        return self._anchor_wall + (log_time_ns - self._anchor_ns) / (self.rate * 1e9)

    def pause(self, now: float) -> None:
        if not self.paused:
            self._anchor_ns, self._anchor_wall = self.bag_time(now), now
            self.paused = True

    def resume(self, now: float) -> None:
        if self.paused:
            self._anchor_wall = now
            self.paused = False

    def restart(self, start_ns: int, now: float) -> None:
        """Back to `start_ns` (the next loop), keeping the rate and the pause state."""
        self._anchor_ns, self._anchor_wall = start_ns, now


def schedule(log_times_ns: Sequence[int], rate: float) -> list[float]:
    """Wall seconds after the start at which each message is due, when nothing pauses the playback."""
    if not log_times_ns:
        return []
    clock = PlaybackClock(min(log_times_ns), rate, 0.0)
    return [clock.due(t) for t in log_times_ns]


def replay_profile(offered_qos_profiles: str) -> QosProfile:
    """The QoS to publish a topic with, from the profiles its publishers offered when it was recorded.

    Latched (transient local) when every recorded publisher was; reliable unless every one was best effort;
    keep-last PLAY_DEPTH (the recorded depth is usually unknown: the graph does not report it). No recorded
    profiles: reliable and volatile, as rosbag2 plays them.
    """
    default = QosProfile(depth=PLAY_DEPTH)
    try:
        profiles = untrusted_yaml.load(offered_qos_profiles, QOS_YAML_DEPTH) if offered_qos_profiles else []
    except untrusted_yaml.UntrustedYamlError:
        return default
    if not isinstance(profiles, list):
        return default
    durability = [p.get('durability') for p in profiles if isinstance(p, dict)]
    reliability = [p.get('reliability') for p in profiles if isinstance(p, dict)]
    latched = bool(durability) and all(d == 'transient_local' for d in durability)
    best_effort = bool(reliability) and all(r == 'best_effort' for r in reliability)
    return replace(default, durability='transient_local' if latched else 'volatile',
                   reliability='best_effort' if best_effort else 'reliable')
