"""Messages a recording may have missed, found from each topic's header stamps.

A topic published once per simulation step (or at any steady rate) has stamps one period apart,
each shared by the same number of messages (8 Range messages per step on ``proximity``). A stamp
step of several periods is a gap (whole steps missing); a stamp carried by fewer messages than
usual is an incomplete step. The period is the typical single step (refined from the steps near
the 10th percentile) and the usual count the 90th percentile, so both hold even when most of a
topic was lost, as long as a tenth of its steps and stamps arrived whole. A periodic topic whose stamps end
periods before the others' is missing its end (a reader that stalled). Only periodic topics
are judged (nearly every step a whole number of periods), so event-driven ones such as
``rosout`` are left alone, as are topics without a stamp first (no ``std_msgs/Header`` or
``builtin_interfaces/Time`` as their first field). No ROS needed.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np

from epuck_ros.bag.cdr import CDR_BE, CDR_LE, ENCAPSULATION
from epuck_ros.bag.reader import Bag, Topic

GAP_FACTOR = 1.5
"""A stamp step of at least this many periods is a gap."""
JITTER = 0.25
"""A step within this fraction of a period of a whole number of periods is regular."""
REGULAR_SHARE = 0.9
"""A topic is periodic when at least this share of its stamp steps are regular (random steps: ~50 %)."""
MIN_STEPS = 10
"""Fewer stamp steps than this say nothing about a period."""
_STAMP_TYPES = ('Header', 'std_msgs/Header', 'std_msgs/msg/Header',
                'builtin_interfaces/Time', 'builtin_interfaces/msg/Time')
_FIRST_FIELD = re.compile(r'^\s*([A-Za-z0-9_/]+)\s+\w+\s*(?:#.*)?$', re.MULTILINE)


@dataclass(frozen=True)
class TopicGaps:
    """What the stamps of one topic say about missing messages."""

    topic: str
    messages: int
    period_ns: int
    per_stamp: int
    gaps: int
    missing_steps: int
    longest_gap_ns: int
    incomplete_steps: int
    missing_in_steps: int
    last_ns: int
    missing_at_end: int = 0
    """Periods between this topic's last stamp and the latest stamp of the bag's periodic topics."""

    @property
    def missing_messages(self) -> int:
        """Estimated messages missing: whole steps times the usual count, plus the holes in incomplete steps."""
        return (self.missing_steps + self.missing_at_end) * self.per_stamp + self.missing_in_steps

    def describe(self) -> str:
        parts = []
        if self.gaps:
            parts.append(f'{self.gaps} stamp gap{"s" * (self.gaps > 1)} ({self.missing_steps} periods missing, '
                         f'longest {self.longest_gap_ns / 1e9:.3f} s)')
        if self.missing_at_end:
            parts.append(f'ends {self.missing_at_end} periods before the other periodic topics')
        if self.incomplete_steps:
            parts.append(f'{self.incomplete_steps} stamp{"s" * (self.incomplete_steps > 1)} with fewer than '
                         f'{self.per_stamp} messages')
        found = '; '.join(parts) or 'no gap'
        return (f'{self.topic}: ~{self.missing_messages} of {self.messages + self.missing_messages} messages '
                f'missing: {found} (usual period {self.period_ns / 1e9:.3f} s, {self.per_stamp} per stamp)')


def is_stamped(topic: Topic) -> bool:
    """Whether the topic's first field is a header or a time (its stamp sits right after the encapsulation)."""
    if topic.schema_encoding != 'ros2msg':
        return False
    match = _FIRST_FIELD.search(topic.schema_text.split('\n===', 1)[0])
    return match is not None and match.group(1) in _STAMP_TYPES


def find_gaps(topic: str, stamps: np.ndarray) -> TopicGaps | None:
    """Gaps in stamps given in arrival order; None when the topic is not periodic or too short to judge."""
    if len(stamps) < 3:
        return None
    starts = np.flatnonzero(np.concatenate(([True], stamps[1:] != stamps[:-1])))
    counts = np.diff(np.append(starts, len(stamps)))
    steps = np.diff(stamps[starts])
    forward = steps[steps > 0]  # a step back is a restart (reset, a new run), not a loss
    if len(forward) < MIN_STEPS:
        return None
    rough = np.percentile(forward, 10, method='lower')  # a step that occurred, so `single` holds it
    single = forward[(forward > 0.5 * rough) & (forward < 1.5 * rough)]
    period = int(np.median(single))
    periods = forward / period
    if np.count_nonzero(np.abs(periods - np.rint(periods)) <= JITTER) < REGULAR_SHARE * len(forward):
        return None  # not a periodic topic
    per_stamp = max(1, int(np.percentile(counts, 90)))
    long_steps = forward[periods >= GAP_FACTOR]
    missing_steps = int(np.sum(np.rint(long_steps / period) - 1)) if len(long_steps) else 0
    inner = counts[1:-1]  # the first and last stamp may be cut by the start and end of the recording
    short = inner[inner < per_stamp]
    return TopicGaps(topic, int(len(stamps)), period, per_stamp, int(len(long_steps)), missing_steps,
                     int(long_steps.max()) if len(long_steps) else 0, int(len(short)),
                     int(np.sum(per_stamp - short)), int(stamps.max()))


def stamps_from_heads(heads: np.ndarray) -> np.ndarray:
    """Stamps (ns) from the first 12 bytes of stamped CDR messages (encapsulation, sec, nanosec); rows that
    are not CDR are left out."""
    little, big = heads[:, 1] == CDR_LE, heads[:, 1] == CDR_BE
    stamp_bytes = np.ascontiguousarray(heads[:, ENCAPSULATION:ENCAPSULATION + 8])
    sec = np.where(little, stamp_bytes[:, :4].copy().view('<i4')[:, 0], stamp_bytes[:, :4].copy().view('>i4')[:, 0])
    nanosec = np.where(little, stamp_bytes[:, 4:].copy().view('<u4')[:, 0], stamp_bytes[:, 4:].copy().view('>u4')[:, 0])
    stamps = sec.astype(np.int64) * 1_000_000_000 + nanosec.astype(np.int64)
    return stamps[little | big]


def bag_gaps(bag: Bag) -> tuple[list[str], list[TopicGaps]]:
    """(periodic topics judged, those with messages missing) of a bag, from the stamp bytes of each message."""
    stamped = sorted(name for name, topic in bag.topics.items()
                     if topic.message_count > MIN_STEPS and topic.message_encoding == 'cdr' and is_stamped(topic))
    heads = bag.message_heads(stamped, ENCAPSULATION + 8)
    judged = [gaps for gaps in (find_gaps(name, stamps_from_heads(rows)) for name, rows in sorted(heads.items()))
              if gaps is not None]
    end = max((gaps.last_ns for gaps in judged), default=0)
    judged = [replace(gaps, missing_at_end=int(np.rint((end - gaps.last_ns) / gaps.period_ns))
                      if end - gaps.last_ns >= GAP_FACTOR * gaps.period_ns else 0) for gaps in judged]
    return [gaps.topic for gaps in judged], [gaps for gaps in judged if gaps.missing_messages]
