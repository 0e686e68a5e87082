"""A condition that may happen thousands of times in a run, logged without flooding the log."""
from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable

SUMMARY_PERIOD = 30.0
"""Wall seconds between two summaries of a repeated condition (command time-outs)."""


class RepeatedCondition:
    """A condition that may happen thousands of times (a robot's command time-out): logged the first time for each
    robot, then counted, with a summary every `SUMMARY_PERIOD` wall seconds and at the end."""

    def __init__(self, log: Callable[[str], None], what: str) -> None:
        self._log, self._what = log, what
        self._counts: Counter[str] = Counter()
        self._unreported: Counter[str] = Counter()
        self._last_summary = time.monotonic()

    def happened(self, robot: str, first_message: str) -> None:
        if not self._counts[robot]:
            self._log(f'{first_message} (further ones are counted, not logged)')
        else:
            self._unreported[robot] += 1
        self._counts[robot] += 1
        if self._unreported and time.monotonic() - self._last_summary > SUMMARY_PERIOD:
            self.summarise()

    def summarise(self) -> None:
        if self._unreported:
            counts = ', '.join(f'{robot} {count}' for robot, count in sorted(self._unreported.items()))
            self._log(f'{self._what} {sum(self._unreported.values())} more times ({counts})')
        self._unreported.clear()
        self._last_summary = time.monotonic()
