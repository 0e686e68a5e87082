"""Lockstep: step a simulation only once every driven robot answered the last step — without ROS.

The step protocol. Every message of a step names it (its stamp, the step's simulated time), and a lockstep
controller's answer names the step it answers (a stamped wheel_cmd, a TwistStamped): `classify` pairs an answer
with the current step by that name, never by arrival order. A robot whose controller has answered with a name is
*in lockstep*: each step waits for its answer, however long (a line every STALL_REPORT while it waits), unless the
user set a `timeout`. A controller recognised by what it sends as one that does not answer each step — answers that
name no step (a plain Twist, an unstamped wheel_cmd: a timer, a joystick) or that name an older step than the one
it is asked — is *free*: its commands drive when they arrive, each step waits at most OWN_RATE_WAIT for it, and
the run is no longer reproducible (`on_free` says so once; so does `on_timeout` for a step that went on without
an answer). Until a controller has answered at all, the step it has not answered is sent again every
RESEND_AFTER: it may have subscribed after the step went out. One that has not answered within FIRST_ANSWER_WAIT
is taken for free too: a timer on simulated time cannot answer before time moves on. Both only over DDS
(`over_dds`): in one process (the headless trials) no step is lost in transit, and a controller that has not
answered yet is still computing its answer (a script that loops without stepping is its time limit's to end).

One `Lockstep` holds all of it: which robots the current step waits for, which answered, the modes, the resends,
and how many controllers must be connected before the first step. The sim node and the headless trials
(`experiments/trial.py`) both step through it, so they step the same way.

Who may step: only the thread that holds the claim (`claim()`; the sim's loop thread, the trial's only thread), and
while it waits for answers (`await_answers`), the thread that delivers a step's last answer, for that one step, if
the holder lends it (`lend()` says so: nothing else due, such as pacing or a pause). Such a step runs under the
object's condition, so the holder cannot stop waiting in the middle of it. `step()` from any other thread raises
`StepClaimError`. Answers may come from any thread.
"""
from __future__ import annotations

import enum
import math
import threading
import time
from collections.abc import Callable, Sequence

RESEND_AFTER = 1.0
"""Wall seconds a step waits for the first answer of a controller before it is sent again."""
FIRST_ANSWER_WAIT = 10.0
"""Wall seconds a controller may take to answer for the first time (a loaded machine starting a Python script)
before it is taken for one that does not answer each step (a timer on simulated time waits for time to move)."""
STALL_REPORT = 5.0
"""Wall seconds between two reports of a step still waiting for answers."""
OWN_RATE_WAIT = 0.01
"""Wall seconds a step waits at most for a free controller: long enough for one that answers this step's /clock
tick (a round trip is well under a millisecond), short enough that the steps it skips cost little."""
GRAPH_POLL = 0.05
"""Wall seconds between two looks at which robots have a controller while lockstep waits for answers."""
CONTROLLERS_REPORT = 5.0
"""Wall seconds between two reports of a first step still waiting for its controllers (`await_controllers`)."""

StepFunction = Callable[[bool], None]
"""Takes one step and publishes it; with True, publishes the last step again instead (a re-sent step)."""


class Answer(enum.Enum):
    """What an answer is to the current step (`Lockstep.classify`)."""

    STEP = 'answers the current step, naming it'
    UNSTAMPED = 'sends commands that name no step'
    BESIDE = 'names no step, beside a controller that answers by name'
    """Another publisher on the robot's commands (a teleop, the view), or its controller's last stop: it drives,
    and answers nothing."""
    STALE = 'answered with a command naming an older step than the current one'
    REPEATED = 'answers a step it has answered already'
    FUTURE = 'names a step the simulation has not reached'
    SILENT = f'did not answer its first step within {FIRST_ANSWER_WAIT:g} s'


class StepClaimError(RuntimeError):
    """A thread stepped without holding the claim."""


def _every_robot(robots: int) -> Callable[[], Sequence[int]]:
    return lambda: range(robots)


class Lockstep:
    """The answers to the current step of `robots` robots, and the one right to step (see the module)."""

    def __init__(self, robots: int, step: StepFunction, timeout: float = 0.0,
                 driven: Callable[[], Sequence[int]] | None = None, lend: Callable[[], bool] = lambda: False,
                 on_stall: Callable[[Sequence[int], float], None] = lambda robots, waited: None,
                 on_resend: Callable[[], None] = lambda: None,
                 on_free: Callable[[int, Answer], None] = lambda robot, answer: None,
                 on_timeout: Callable[[Sequence[int]], None] = lambda robots: None, over_dds: bool = True) -> None:
        """`timeout`: wall seconds a step waits for the answers of controllers in lockstep, 0 = as long as it takes;
        `driven()`: the robots that have a controller now (default: all); `lend()`: whether the thread of a step's
        last answer takes the next step (asked under the condition while the holder waits, so nothing the holder
        writes changes meanwhile); `on_stall(robots, waited)`: every STALL_REPORT while a step waits for them;
        `on_resend()`: the step is about to be sent again; `on_free(robot, answer)`: that robot's controller is
        free from now on, for what its answer was; `on_timeout(robots)`: the step goes on without their answers;
        `over_dds`: steps and answers travel over DDS (resends and the first answer's wait, see the module)."""
        self._robots = robots
        self._step = step
        self._timeout = timeout if timeout > 0.0 else math.inf
        self._driven = driven or _every_robot(robots)
        self._lend = lend
        self._on_stall, self._on_resend, self._on_free, self._on_timeout = on_stall, on_resend, on_free, on_timeout
        self._over_dds = over_dds
        self._holder: int | None = None
        """The thread (ident) that may step now."""
        self._changed = threading.Condition()
        """Guards everything below; notified when the answers the holder waits for are in."""
        self._answered = [False] * robots
        """An answer to the current step arrived."""
        self._answered_once = [False] * robots
        self._declared = [False] * robots
        """The robot's controller declared it answers each step by name (`declare`): never free for silence."""
        self._free = [False] * robots
        """The controller does not answer each step (see the module): waited for at most OWN_RATE_WAIT."""
        self._first_awaited: dict[int, float] = {}
        """When each robot that never answered was first awaited (monotonic s): FIRST_ANSWER_WAIT counts from it."""
        self._last_named: list[int | None] = [None] * robots
        """The step (ns) the robot's last named answer named: a second answer to it is a repeat."""
        self._awaited: set[int] = set()
        """Robots in lockstep (or not yet answered) whose answer to the current step is still awaited."""
        self._free_awaited: set[int] = set()
        """Free robots that have not answered the current step: waited for until `_own_rate_deadline`."""
        self._parked = False
        """The holder waits for the current step's answers (`await_answers`)."""
        self._started = self._deadline = self._own_rate_deadline = 0.0
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
        """Take one step, or send the last one again, by the claim's holder; its answers are awaited from now on.
        A step sent again keeps the answers it has (a repeat of them is not counted again)."""
        if self._holder != threading.get_ident():
            raise StepClaimError(f'thread {threading.current_thread().name} stepped without the claim')
        if not resend:
            with self._changed:
                self._answered = [False] * self._robots
        self._step(resend)

    def await_answers(self) -> bool:
        """Wait until every driven robot answered the step just taken (see the module); False: send it again.

        Who has a controller is read once per step and every GRAPH_POLL while waiting; `answer` wakes this thread
        only once the last awaited answer is in. Meanwhile the thread of a step's last answer may take the next
        step (see the module): this thread then goes on waiting, for the answers of each new step."""
        if self._holder != threading.get_ident():
            raise StepClaimError(f'thread {threading.current_thread().name} waits for answers without the claim')
        with self._changed:
            self._expect()
            self._parked = True
            try:
                return self._wait_for_answers()
            finally:
                self._parked = False

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

    def declare(self, robots: Sequence[int]) -> None:
        """These robots' controller declared, before any answer, that it answers each of their steps by name (a swarm
        controller's declaration, nodes/swarm_ports.py): however long its first answer takes, it is waited for, never
        taken for free after FIRST_ANSWER_WAIT (whether a controller is in lockstep never depends on a wall clock)."""
        with self._changed:
            for robot in robots:
                self._declared[robot] = True

    def classify(self, robot: int, named: int | None, current: int) -> Answer:
        """What an answer of `robot` naming step `named` (ns; None: it names none) is while step `current` (ns) is
        out. A repeat (a step sent again, answered twice) and a step not reached yet are the caller's to drop; the
        others drive, and all but BESIDE answer (`answer`)."""
        with self._changed:
            if named is None:
                return Answer.BESIDE if self._last_named[robot] is not None else Answer.UNSTAMPED
            if named == self._last_named[robot]:
                return Answer.REPEATED
            if named > current:
                return Answer.FUTURE
            return Answer.STEP if named == current else Answer.STALE

    def answer(self, robot: int, kind: Answer = Answer.STEP, named: int | None = None) -> None:
        """An answer of `robot` (`kind`: `classify`'s verdict, STEP, STALE or UNSTAMPED; `named`: the step it names)
        was applied. If it was the step's last awaited answer and the holder, waiting, lends its claim, the next
        step is taken here, in the calling thread."""
        with self._changed:
            if named is not None:
                self._last_named[robot] = named
            if kind is not Answer.STEP:
                self._make_free(robot, kind)
            self._answered[robot] = True
            self._awaited.discard(robot)
            self._free_awaited.discard(robot)
            if self._awaited or not self._parked:
                return   # more answers to come, or nobody waits for them yet
            if self._free_awaited or self._closed or self._required or not self._lend():
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
        """Until the answers are in or may be done without (True), or the step is to be sent again (False)."""
        next_report = self._started + STALL_REPORT
        while True:
            now = time.monotonic()
            free_done = not self._free_awaited or now >= self._own_rate_deadline
            if (not self._awaited and free_done) or self._closed:
                self._take_answers()
                return True
            if self._awaited and now >= self._deadline:
                self._on_timeout(sorted(self._awaited))
                self._take_answers()
                return True
            unanswered = [robot for robot in self._awaited if not self._answered_once[robot]] if self._over_dds else []
            for robot in unanswered:
                waited = now - self._first_awaited.setdefault(robot, now)
                if waited >= FIRST_ANSWER_WAIT and not self._declared[robot]:
                    self._make_free(robot, Answer.SILENT)
            if unanswered and not self._awaited:
                continue
            if unanswered and now - self._started >= RESEND_AFTER:
                self._on_resend()
                return False
            if self._awaited and now >= next_report:
                self._on_stall(sorted(self._awaited), now - self._started)
                next_report += STALL_REPORT
            if self._awaited:
                until = min(self._deadline, next_report, now + GRAPH_POLL,
                            self._started + RESEND_AFTER if unanswered else math.inf)
            else:
                until = self._own_rate_deadline
            if not self._changed.wait(max(0.0, until - now)):
                self._read_graph()

    def _make_free(self, robot: int, why: Answer) -> None:
        """From now on `robot`'s controller is not waited for beyond OWN_RATE_WAIT (said once)."""
        if not self._free[robot]:
            self._free[robot] = True
            self._awaited.discard(robot)
            self._on_free(robot, why)

    def _expect(self) -> None:
        """A step is out: wait for its answers from now on."""
        now = time.monotonic()
        self._started = now
        self._deadline, self._own_rate_deadline = now + self._timeout, now + OWN_RATE_WAIT
        self._read_graph()

    def _read_graph(self) -> None:
        """Which robots' answers the current step waits for: those with a controller, in lockstep or free."""
        driven = list(self._driven())
        self._awaited = {robot for robot in driven if not self._answered[robot] and not self._free[robot]}
        self._free_awaited = {robot for robot in driven if not self._answered[robot] and self._free[robot]}

    def _take_answers(self) -> None:
        """The current step is answered: note who answered, and clear the answers, so that no thread takes them
        for the next step's."""
        for robot, answered in enumerate(self._answered):
            if answered:
                self._answered_once[robot] = True
        self._answered = [False] * self._robots
        self._awaited, self._free_awaited = set(), set()
