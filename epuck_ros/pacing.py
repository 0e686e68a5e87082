"""How fast the sim's loop runs: its run-time settings (`Controls`) and the sleeps that pace it (`Pacer`).

No ROS here: the node writes the settings from its parameters and its `step` service; the loop reads them.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

PACING_SLICE = 0.02
"""Pacing sleeps at most this long at a time, then reads the real-time factor again: a change takes effect at once."""


@dataclass(frozen=True)
class Settings:
    """What the parameters ask of the loop now."""

    real_time_factor: float
    paused: bool
    pause_at: float


class Controls:
    """The loop's settings and the `step` service's requests, under one condition that also wakes the loop.

    Written by the executor thread (parameters, the `step` service) and by whichever thread steps onto `pause_at`;
    read by the loop thread and by the thread that steps on a lockstep answer. `settings` is an immutable snapshot,
    so a reader sees one consistent set."""

    def __init__(self, settings: Settings) -> None:
        self._changed = threading.Condition()
        self._settings = settings
        self._step_requests = 0
        self._closed = False

    @property
    def settings(self) -> Settings:
        with self._changed:
            return self._settings

    def update(self, **changes: float | bool) -> None:
        """New settings (Settings' fields), effective at once: a loop idling or pacing wakes up."""
        with self._changed:
            self._settings = replace(self._settings, **changes)
            self._changed.notify_all()

    def idle(self) -> bool:
        """Paused, and no step asked for: nothing to step."""
        with self._changed:
            return self._settings.paused and not self._step_requests

    def steps_requested(self) -> bool:
        with self._changed:
            return self._step_requests > 0

    def wait_while_idle(self, timeout: float) -> None:
        """Return once something changed (or after `timeout`) if idle, else at once."""
        with self._changed:
            if self._settings.paused and not self._step_requests and not self._closed:
                self._changed.wait(timeout)

    def request_step(self, done: Callable[[], bool], timeout: float) -> bool:
        """Ask for one step while paused; True once `done()` (the step is out), False after `timeout` or at close."""
        with self._changed:
            self._step_requests += 1
            self._changed.notify_all()
            return self._changed.wait_for(lambda: done() or self._closed, timeout=timeout) and not self._closed

    def stepped(self) -> None:
        """A step was taken: it answers one request, if any."""
        with self._changed:
            if self._step_requests:
                self._step_requests -= 1
                self._changed.notify_all()

    def close(self) -> None:
        """The loop is ending: nothing waits any more."""
        with self._changed:
            self._closed = True
            self._changed.notify_all()


class Pacer:
    """Sleeps so that simulated time runs `factor` times wall time (factor 0: no sleep at all).

    The sleep is cut into short slices and the factor read again after each, so a change of the factor takes
    effect within a slice, whatever the factor was (1e-300 included: nothing divides by it)."""

    FALL_BEHIND = 0.5
    """Wall seconds behind schedule after which pacing starts afresh instead of bursting to catch up."""

    def __init__(self) -> None:
        self._origin: tuple[float, float, float] | None = None  # wall time, sim time, factor

    def restart(self) -> None:
        self._origin = None

    def wait(self, sim_time: float, factor: Callable[[], float], keep_waiting: Callable[[], bool]) -> None:
        """Return once wall time has caught up with `sim_time` at the current `factor()`."""
        while keep_waiting():
            rate, now = factor(), time.monotonic()
            if rate <= 0.0 or self._origin is None or self._origin[2] != rate:
                self._origin = (now, sim_time, rate)  # a new rate paces from this step on
                return
            wall_origin, sim_origin, _ = self._origin
            ahead = (sim_time - sim_origin) - rate * (now - wall_origin)  # simulated seconds ahead of schedule
            if ahead <= 0.0:
                if -ahead > rate * self.FALL_BEHIND:
                    self._origin = (now, sim_time, rate)
                return
            time.sleep(PACING_SLICE if ahead >= rate * PACING_SLICE else ahead / rate)
