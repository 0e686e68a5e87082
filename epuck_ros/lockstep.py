"""Lockstep: step a simulation only once every driven robot answered the last step — without ROS.

One `Lockstep` holds all of it: which robots the current step waits for (those with a controller, else any
answer), which answered, the timeout, the controllers found to answer at their own rate, the re-sent first
step, and how many controllers must be connected before the first step. The sim node and the headless trials
(`experiments/trial.py`) both step through it, so they step the same way.

Who may step: only the thread that holds the claim (`claim()`; the sim's loop thread, the trial's only thread), and
while it waits for answers (`await_answers`), the thread that delivers a step's last answer, for that one step, if
the holder lends it (`lend()` says so: nothing else due, such as pacing or a pause). Such a step runs under the
object's condition, so the holder cannot stop waiting in the middle of it. `step()` from any other thread raises
`StepClaimError`. Answers may come from any thread.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence

LOCKSTEP_START_RESENDS = 3
"""Times an unanswered first step is sent again (one `timeout` each) before the simulation goes on."""
OWN_RATE_AFTER = 2
"""Steps in a row a controller that has answered before may leave unanswered until the timeout before lockstep
takes it for one that answers at its own rate (a timer), not every step: waiting a `timeout` for each
step it skips made a 10 Hz controller run at a few per cent of real time."""
OWN_RATE_WAIT = 0.01
"""Wall seconds a step waits at most for controllers that answer at their own rate: long enough for one that
answers this step's /clock tick (a round trip is well under a millisecond), short enough that the steps it skips
cost little."""
GRAPH_POLL = 0.05
"""Wall seconds between two looks at which robots have a controller while lockstep waits for answers."""
CONTROLLERS_REPORT = 5.0
"""Wall seconds between two reports of a first step still waiting for its controllers (`await_controllers`)."""

StepFunction = Callable[[bool], None]
"""Takes one step and publishes it; with True, publishes the last step again instead (a re-sent first step)."""


class StepClaimError(RuntimeError):
    """A thread stepped without holding the claim."""


def _every_robot(robots: int) -> Callable[[], Sequence[int]]:
    return lambda: range(robots)


class Lockstep:
    """The answers to the current step of `robots` robots, and the one right to step (see the module)."""

    def __init__(self, robots: int, step: StepFunction, timeout: float,
                 driven: Callable[[], Sequence[int]] | None = None, lend: Callable[[], bool] = lambda: False,
                 on_own_rate: Callable[[int], None] = lambda robot: None,
                 on_resend: Callable[[], None] = lambda: None) -> None:
        """`driven()`: the robots that have a controller now (default: all); `lend()`: whether the thread of a step's
        last answer takes the next step (asked under the condition while the holder waits, so nothing the holder
        writes changes meanwhile); `on_own_rate(robot)`: that robot's controller was found to answer at its own rate;
        `on_resend()`: the first step is about to be sent again."""
        self._robots = robots
        self._step = step
        self._timeout = timeout
        self._driven = driven or _every_robot(robots)
        self._lend, self._on_own_rate, self._on_resend = lend, on_own_rate, on_resend
        self._holder: int | None = None
        """The thread (ident) that may step now."""
        self._changed = threading.Condition()
        """Guards everything below; notified when the answers the holder waits for are in."""
        self._answered = [False] * robots
        """A command arrived since the current step was published."""
        self._answered_once = [False] * robots
        self._missed = [0] * robots
        """Steps in a row a controller, having answered before, left unanswered until the timeout."""
        self._own_rate = [False] * robots
        """The controller answers at its own rate, not every step: each step waits at most OWN_RATE_WAIT for it."""
        self._awaited: set[int] = set()
        """The robots whose answer to the current step is still awaited (empty: any answer completes the step)."""
        self._waiting_for: Sequence[int] = range(robots)
        """The robots whose answers the current step waits for (those driven, else all of them)."""
        self._any_answer = True
        """No robot has a controller: any command answers the step."""
        self._parked = False
        """The holder waits for the current step's answers (`await_answers`)."""
        self._deadline = self._own_rate_deadline = 0.0
        self._resends = 0
        self._required = 0
        """Controllers to be connected before the next step (`require_controllers`); 0 once they were."""
        self._closed = False

    # --- the holder's side ------------------------------------------------------------------------------

    def claim(self) -> None:
        """The calling thread becomes the one that steps."""
        with self._changed:
            self._holder = threading.get_ident()

    def await_controllers(self, keep_waiting: Callable[[], bool],
                          report: Callable[[int, Sequence[int]], None]) -> bool:
        """Before a step: until as many robots have a controller as `require_controllers` asked (True), or until
        `keep_waiting()` turns false or lockstep closes (False). `report(required, driven)` every CONTROLLERS_REPORT.

        The graph cannot tell a controller on its way: whoever starts the controllers and resumes the simulation
        saw them in its own view of the graph, which runs ahead of the simulator's matching by up to a discovery
        round (seconds under load). Stepping meanwhile would start the late ones a few steps behind."""
        last_report = time.monotonic()
        with self._changed:
            while self._required:
                driven = list(self._driven())
                if len(driven) >= self._required:
                    self._required = 0
                    break
                if self._closed or not keep_waiting():
                    return False
                if time.monotonic() - last_report >= CONTROLLERS_REPORT:
                    last_report = time.monotonic()
                    report(self._required, driven)
                self._changed.wait(GRAPH_POLL)
            return not self._closed

    def step(self, resend: bool = False) -> None:
        """Take one step, or send the last one again, by the claim's holder; its answers are awaited from now on."""
        if self._holder != threading.get_ident():
            raise StepClaimError(f'thread {threading.current_thread().name} stepped without the claim')
        with self._changed:
            self._answered = [False] * self._robots
        self._step(resend)

    def await_answers(self) -> bool:
        """Wait until every robot with a controller answered the step just taken; False: send it again.

        A robot nobody drives holds nobody up; with no controller at all any command answers, up to the timeout.
        Until a robot's controller has answered once, a step it did not answer is sent again rather than passed: a
        controller still connecting may have missed it, and two runs would then start a step apart. A few resends
        at most, so a lost first answer cannot hang the simulation. Who has a controller is read once per step and
        every GRAPH_POLL while waiting; `answer` wakes this thread only once the last awaited answer is in. Meanwhile
        the thread of a step's last answer may take the next step (see the module): this thread then goes on
        waiting, for the answers of each new step."""
        if self._holder != threading.get_ident():
            raise StepClaimError(f'thread {threading.current_thread().name} waits for answers without the claim')
        with self._changed:
            self._expect()
            self._parked = True
            try:
                if self._wait_for_answers():
                    return True
            finally:
                self._parked = False
            return self._after_timeout()

    def require_controllers(self, count: int) -> None:
        """No step (from any thread) until `count` robots have a controller; once they had, no such wait again."""
        with self._changed:
            self._required = count
            self._changed.notify_all()

    def close(self) -> None:
        """Stop waiting for answers (the simulation is ending)."""
        with self._changed:
            self._closed = True
            self._changed.notify_all()

    # --- the answers' side ------------------------------------------------------------------------------

    def answer(self, robot: int) -> None:
        """A command for `robot` arrived: it answers the current step. If that was the step's last awaited answer
        and the holder, waiting, lends its claim, the next step is taken here, in the calling thread."""
        with self._changed:
            self._answered[robot] = True
            self._awaited.discard(robot)
            if self._awaited or not self._parked:
                return   # more answers to come, or nobody waits for them yet
            if self._closed or self._required or not self._lend():
                self._changed.notify()
                return
            self._take_answers()
            holder, self._holder = self._holder, threading.get_ident()
            try:
                self.step()
            finally:
                self._holder = holder
            self._expect()

    # --- under the condition ----------------------------------------------------------------------------

    def _wait_for_answers(self) -> bool:
        """Until the answers are in (True), or the time for them is over."""
        while True:
            if (any if self._any_answer else all)(self._answered[robot] for robot in self._waiting_for):
                self._take_answers()
                return True
            own_rate_only = not self._any_answer and all(
                self._own_rate[robot] for robot in self._waiting_for if not self._answered[robot])
            remaining = (self._own_rate_deadline if own_rate_only else self._deadline) - time.monotonic()
            if remaining <= 0.0 or self._closed:
                return False
            if not self._changed.wait(min(remaining, GRAPH_POLL)):
                self._read_graph()

    def _after_timeout(self) -> bool:
        """The answers did not all come: go on (True), or send a step nobody answered yet again (False)."""
        if time.monotonic() < self._deadline and not self._closed:
            return True   # only controllers at their own rate were missing: no resend, no count
        self._note_own_rate()
        never_answered = [robot for robot in self._waiting_for if not self._answered_once[robot]]
        if not never_answered or self._resends >= LOCKSTEP_START_RESENDS or self._closed:
            return True
        self._resends += 1
        self._on_resend()
        return False

    def _note_own_rate(self) -> None:
        """After a step timed out: count it for each controller that answered before but not this step; past
        `OWN_RATE_AFTER` in a row, wait at most `OWN_RATE_WAIT` for it from then on."""
        for robot in self._waiting_for:
            if self._answered[robot] or not self._answered_once[robot]:
                self._missed[robot] = 0 if self._answered[robot] else self._missed[robot]
                continue
            self._missed[robot] += 1
            if self._missed[robot] >= OWN_RATE_AFTER and not self._own_rate[robot]:
                self._own_rate[robot] = True
                self._on_own_rate(robot)

    def _expect(self) -> None:
        """A step is out: wait for its answers from now on, up to the timeout."""
        now = time.monotonic()
        self._deadline, self._own_rate_deadline = now + self._timeout, now + OWN_RATE_WAIT
        self._read_graph()

    def _read_graph(self) -> None:
        """Which robots' answers the current step waits for: those with a controller."""
        driven = list(self._driven())
        self._any_answer = not driven
        self._waiting_for = driven or range(self._robots)
        self._awaited = {robot for robot in driven if not self._answered[robot]}

    def _take_answers(self) -> None:
        """The current step is answered: note who answered, and clear the answers, so that no thread takes them
        for the next step's."""
        for robot in self._waiting_for:
            if self._answered[robot]:
                self._answered_once[robot] = True
                self._missed[robot] = 0
        self._answered = [False] * self._robots
