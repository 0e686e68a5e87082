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

Stamps follow one of two clocks: simulated time (from 0 when the simulator starts) or the wall clock (from
1970: `rosout` and any node without `use_sim_time`). A topic is compared only with topics of its own clock, and
what it can be missing is bounded by the bag itself: the span its clock's periodic topics cover, in periods.
Why: a wall-clock `rosout` whose stamps fell on multiples of the step was once taken for a periodic topic, its
stamps (years after the simulation's) became the end every simulated topic missed, and a small bag was reported
missing billions of messages.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from epuck_ros.bag.cdr import CDR_BE, CDR_LE, ENCAPSULATION
from epuck_ros.bag.lockstep_status import recorded_integrity
from epuck_ros.bag.reader import Bag, Topic
from epuck_ros.bag.steps import (ANSWER_TOPICS, SENSES_ON_TOPIC, first_field_is_stamp, senses_on_from_text,
                                 step_reader)
from epuck_ros.conversions import NS_PER_SECOND

GAP_FACTOR = 1.5
"""A stamp step of at least this many periods is a gap."""
JITTER = 0.25
"""A step within this fraction of a period of a whole number of periods is regular."""
REGULAR_SHARE = 0.9
"""A topic is periodic when at least this share of its stamp steps are regular (random steps: ~50 %)."""
MIN_STEPS = 10
"""Fewer stamp steps than this say nothing about a period."""
COVERAGE = 0.1
"""A periodic topic has stamps on at least this share of the periods it spans (one that lost 90 % still does);
event topics whose stamps fall on the step grid (a log line now and then) do not."""
WALL_CLOCK_FROM = 10**18
"""Stamps from this many ns (2001-09-09 on the wall clock; 31.7 years of simulated time) are wall-clock stamps."""


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
    first_ns: int = 0
    limit: int | None = None
    """At most this many messages can be missing (what the bag's own span allows); None: not bounded yet."""
    missing_at_end: int = 0
    """Periods between this topic's last stamp and the latest stamp of the periodic topics on its clock."""

    @property
    def wall_clock(self) -> bool:
        """Whether the stamps count from 1970 (wall clock) rather than from the simulator's start."""
        return self.last_ns >= WALL_CLOCK_FROM

    @property
    def missing_messages(self) -> int:
        """Estimated messages missing: whole steps times the usual count, plus the holes in incomplete steps."""
        estimate = (self.missing_steps + self.missing_at_end) * self.per_stamp + self.missing_in_steps
        return estimate if self.limit is None else min(estimate, self.limit)

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
    return topic.schema_encoding == 'ros2msg' and first_field_is_stamp(topic.schema_text)


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
    if len(starts) < COVERAGE * (np.sum(np.rint(periods)) + 1):
        return None  # whole periods apart but far between: events on the step grid
    per_stamp = max(1, int(np.percentile(counts, 90)))
    long_steps = forward[periods >= GAP_FACTOR]
    missing_steps = int(np.sum(np.rint(long_steps / period) - 1)) if len(long_steps) else 0
    inner = counts[1:-1]  # the first and last stamp may be cut by the start and end of the recording
    short = inner[inner < per_stamp]
    return TopicGaps(topic, int(len(stamps)), period, per_stamp, int(len(long_steps)), missing_steps,
                     int(long_steps.max()) if len(long_steps) else 0, int(len(short)),
                     int(np.sum(per_stamp - short)), int(stamps.max()), int(stamps.min()))


def stamps_from_heads(heads: np.ndarray) -> np.ndarray:
    """Stamps (ns) from the first 12 bytes of stamped CDR messages (encapsulation, sec, nanosec); rows that
    are not CDR are left out."""
    little, big = heads[:, 1] == CDR_LE, heads[:, 1] == CDR_BE
    stamp_bytes = np.ascontiguousarray(heads[:, ENCAPSULATION:ENCAPSULATION + 8])
    sec = np.where(little, stamp_bytes[:, :4].copy().view('<i4')[:, 0], stamp_bytes[:, :4].copy().view('>i4')[:, 0])
    nanosec = np.where(little, stamp_bytes[:, 4:].copy().view('<u4')[:, 0], stamp_bytes[:, 4:].copy().view('>u4')[:, 0])
    stamps = sec.astype(np.int64) * NS_PER_SECOND + nanosec.astype(np.int64)
    return stamps[little | big]


@dataclass(frozen=True)
class AnswerGaps:
    """The steps of a bag's /clock that a robot's controller answered by name and those it did not."""

    topic: str
    steps: int
    """The steps it should have answered: from its first answer to the step before the last /clock."""
    missing: int
    first_missing_ns: int

    @property
    def missing_messages(self) -> int:
        return self.missing

    def describe(self) -> str:
        return (f'{self.topic}: {self.missing} of {self.steps} steps have no answer naming them (first at '
                f't={self.first_missing_ns / NS_PER_SECOND:.3f} s)')


def answer_gaps(bag: Bag) -> tuple[list[str], list[AnswerGaps]]:
    """Per answer topic whose messages name steps (a lockstep controller's `wheel_cmd` or stamped `cmd_vel`), the
    steps of the bag's `/clock` without an answer naming them, from its first answer to the step before the last
    (the answer to the last step drives nothing: a recorder leaves it out). Only while the run was lockstep, as its
    `lockstep_status` says (a controller at its own rate, or with `--no-lockstep`, skips steps without anything being
    lost): a bag without one is not checked. Returns (topics checked, those with steps unanswered)."""
    integrity = recorded_integrity(bag) if '/clock' in bag.topics else None
    if integrity is None or (not integrity.reproducible and integrity.since is None):
        return [], []
    held_until = None if integrity.reproducible else round(integrity.since * NS_PER_SECOND)
    clock = np.unique(stamps_from_heads(next(iter(bag.message_heads(['/clock'], ENCAPSULATION + 8).values()),
                                             np.zeros((0, ENCAPSULATION + 8), np.uint8))))
    checked, found = [], []
    for name, topic in sorted(bag.topics.items()):
        reader = step_reader(topic.type_name, topic.schema_text)
        if name.rsplit('/', 1)[-1] not in ANSWER_TOPICS or reader is None or len(clock) < 2:
            continue
        named = {step for step in (reader(message.data) for message in bag.messages([name])) if step is not None}
        if not named:
            continue   # a controller at its own rate: its commands name no step
        checked.append(name)
        due = clock[(clock >= min(named)) & (clock < clock[-1])]
        due = due if held_until is None else due[due < held_until]
        missing = due[~np.isin(due, np.fromiter(named, np.int64, len(named)))]
        if len(missing):
            found.append(AnswerGaps(name, int(len(due)), int(len(missing)), int(missing[0])))
    return checked, found


def bag_gaps(bag: Bag) -> tuple[list[str], list[TopicGaps | AnswerGaps]]:
    """(topics judged, those with messages missing) of a bag: the periodic stamped topics, from the stamp bytes of
    each message, and the answer topics against the steps (`answer_gaps`)."""
    stamped = sorted(name for name, topic in bag.topics.items()
                     if topic.message_count > MIN_STEPS and topic.message_encoding == 'cdr' and is_stamped(topic))
    heads = bag.message_heads(stamped, ENCAPSULATION + 8)
    stamps = {name: stamps_from_heads(rows) for name, rows in heads.items()}
    judged = [gaps for gaps in (find_gaps(name, stamps[name]) for name in sorted(stamps)) if gaps is not None]
    judged = [_bounded(_with_end(gaps, [other for other in judged if other.wall_clock == gaps.wall_clock]))
              for gaps in judged]
    senses = senses_on(bag)
    judged = [_sense_steps(gaps, stamps[gaps.topic], senses[gaps.topic], judged) if gaps.topic in senses else gaps
              for gaps in judged]
    answered, answers = answer_gaps(bag)
    return ([gaps.topic for gaps in judged] + answered,
            [gaps for gaps in judged if gaps.missing_messages] + answers)


def senses_on(bag: Bag) -> dict[str, list[tuple[int, bool]]]:
    """Per sense topic of a robot with a `senses_on` topic in the bag, its changes: (after ns, published from the
    step after on), in order (`bag.steps.senses_on_text`)."""
    changes: dict[str, list[tuple[int, bool]]] = {}
    for name in sorted(bag.topics):
        if name.rsplit('/', 1)[-1] != SENSES_ON_TOPIC or bag.topics[name].type_name != 'std_msgs/msg/String':
            continue
        prefix = name[:-len(SENSES_ON_TOPIC)]
        said = [read for read in (senses_on_from_text(_string(message.data)) for message in bag.messages([name]))
                if read is not None]
        for relative in {topic for _, topics in said for topic in topics}:
            changes[prefix + relative] = [(after, relative in topics) for after, topics in sorted(said)]
    return changes


def _string(data: bytes) -> str:
    """A little-endian CDR std_msgs/String's text ('' for anything else)."""
    if len(data) < ENCAPSULATION + 4 or data[1] != CDR_LE:
        return ''
    length = int(np.frombuffer(data, '<u4', 1, ENCAPSULATION)[0])
    return data[ENCAPSULATION + 4:ENCAPSULATION + 4 + length].rstrip(b'\0').decode('utf-8', errors='replace')


def _sense_steps(gaps: TopicGaps, stamps: np.ndarray, changes: list[tuple[int, bool]],
                 judged: list[TopicGaps]) -> TopicGaps:
    """`gaps` of a sense topic counted only over the steps its sense was on (`senses_on`): from the bag's first
    step of its clock to the last, the steps without a message are missing only while it was published."""
    period = gaps.period_ns
    same_clock = [other for other in judged if other.wall_clock == gaps.wall_clock]
    first = round(min(other.first_ns for other in same_clock) / period)
    last = round(max(other.last_ns for other in same_clock) / period)
    steps = np.arange(first, last + 1)
    on = np.zeros(len(steps), bool)
    for after, published in changes:
        on[steps > round(after / period)] = published
    present = np.isin(steps, np.rint(stamps / period).astype(np.int64))
    missing = on & ~present
    runs = np.flatnonzero(np.diff(np.concatenate(([0], missing.astype(np.int8), [0]))))
    starts, ends = runs[::2], runs[1::2]
    at_end = int(ends[-1] - starts[-1]) if len(starts) and ends[-1] == len(steps) else 0
    inner = len(starts) - (1 if at_end else 0)
    lengths = (ends - starts)[:inner]
    return replace(gaps, gaps=int(inner), missing_steps=int(lengths.sum()),
                   longest_gap_ns=int((lengths.max() + 1) * period) if inner else 0, missing_at_end=at_end, limit=None)


def _with_end(gaps: TopicGaps, same_clock: list[TopicGaps]) -> TopicGaps:
    """`gaps` with the periods it misses before the end of the other periodic topics of its clock."""
    behind = max(other.last_ns for other in same_clock) - gaps.last_ns
    return replace(gaps, missing_at_end=int(np.rint(behind / gaps.period_ns)) if behind >= GAP_FACTOR * gaps.period_ns
                   else 0)


def _bounded(gaps: TopicGaps) -> TopicGaps:
    """`gaps` with what it may report bounded by the bag: the periods from its first stamp to its clock's end,
    `per_stamp` messages each, less the messages present."""
    periods = (gaps.last_ns - gaps.first_ns) // gaps.period_ns + 1 + gaps.missing_at_end
    return replace(gaps, limit=max(0, int(periods) * gaps.per_stamp - gaps.messages))
