"""Whether a run is reproducible, said the same way by the simulator, `bringup`, the `epuck_sim` fixture and
`bag summary` — without ROS.

A lockstep run is a function of (world, robots, seed, duration, noise, controllers) as long as every step was
answered, by name, by each driven robot's controller (epuck_ros/lockstep.py). The simulator publishes what it
knows on its latched `lockstep_status` topic (diagnostic_msgs/DiagnosticStatus, so `ros2 topic echo`, rqt and
Foxglove show it, and a bag carries it): level OK while the run holds, WARN from the first thing that broke it,
with the reason and the simulated time. The status's fields are built and read here, in one place.
"""
from __future__ import annotations

from dataclasses import dataclass

STATUS_TOPIC = 'lockstep_status'
STATUS_TYPE = 'diagnostic_msgs/msg/DiagnosticStatus'
STATUS_NAME = 'lockstep'
"""The status's `name` field."""
OK, WARN = 0, 1
"""DiagnosticStatus levels (bytes in the message)."""
REPRODUCIBLE_KEY, SINCE_KEY = 'reproducible', 'broken_at'


@dataclass(frozen=True)
class Integrity:
    """A run's verdict: reproducible, or why not (and from which simulated time)."""

    reproducible: bool
    reason: str = ''
    since: float | None = None
    """Simulated seconds at which it stopped being reproducible."""

    @property
    def message(self) -> str:
        """The status's message: `reproducible: ...` or `not reproducible: ...`."""
        return ('' if self.reproducible else 'not ') + 'reproducible: ' + self._why

    @property
    def verdict(self) -> str:
        """`yes, ...` or `no, ...`: the answer to "reproducible?" (bag summary)."""
        return ('yes, ' if self.reproducible else 'no, ') + self._why

    @property
    def _why(self) -> str:
        if self.reproducible:
            return 'every step was answered by every driven robot\'s controller, by name (lockstep)'
        return self.reason + (f' (from t={self.since:.3f} s)' if self.since is not None else '')

    def fields(self) -> tuple[int, str, str, list[tuple[str, str]]]:
        """(level, name, message, key-value pairs) of its DiagnosticStatus."""
        values = [(REPRODUCIBLE_KEY, str(self.reproducible).lower())]
        if self.since is not None:
            values.append((SINCE_KEY, repr(self.since)))
        return (OK if self.reproducible else WARN), STATUS_NAME, self.message, values


HELD = Integrity(True)
NOT_LOCKSTEP = Integrity(False, 'the simulator is not in lockstep: it keeps its own pace, and what the controllers '
                                'see depends on the machine\'s load')


def integrity_from(message: str, values: dict[str, str]) -> Integrity:
    """The verdict a DiagnosticStatus carries (its message and key-values)."""
    if values.get(REPRODUCIBLE_KEY) == 'true':
        return HELD
    try:
        since = float(values[SINCE_KEY])
    except (KeyError, ValueError):   # a bag's status is untrusted input: its message is all there is
        since = None
    reason = message.removeprefix('not reproducible: ')
    if since is not None:
        reason = reason.removesuffix(f' (from t={since:.3f} s)')
    return Integrity(False, reason, since)
