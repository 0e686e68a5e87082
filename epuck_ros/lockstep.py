"""Lockstep: step a simulation only once every driven robot answered the last step — without ROS.

The step protocol. Every message of a step names it (its stamp, the step's simulated time), and a lockstep
controller's answer names the step it answers (a stamped wheel_cmd, a TwistStamped): `classify` pairs an answer with
the current step by that name, never by arrival order. A robot whose controller has answered with a name is *in
lockstep*: each step waits for its answer, however long (a line every STALL_REPORT while it waits), unless the user
set a `timeout` — also once its controller has left the graph (a process stopped, frozen or crashed leaves no word,
and DDS drops it after its lease): it may come back, and when a controller of that robot is seen again the step is
sent again. Stepping on without it would make the rest of the run depend on the moment it left. A controller that
ends on purpose while the simulation runs says goodbye: it declares its own rate for its topics (see below), and
once it has left the graph its robot is no longer waited for (its last answer drives on, whenever the simulator
learns it: the run stays a function of the answers). A controller recognised by what it sends as one that does not
answer each step — answers that name no step (a plain Twist, an unstamped wheel_cmd: a timer, a joystick) or that
name an older step than the one it is asked — is *free*: its commands drive when they arrive, each step waits at
most OWN_RATE_WAIT for it, and the run is no longer reproducible (`on_free` says so once; so does `on_timeout` for a
step that went on without an answer). Until a controller has answered at all, the step it has not answered is sent
again every RESEND_AFTER: it may have subscribed after the step went out. Before its first answer the graph and the
controller's declaration say what to expect (`Controller`, `controller()`): one declared in lockstep is waited for
as long as it takes; one that publishes only a type that cannot name a step (plain Twist), or that declared its own
rate, is free from the moment the graph shows it (it is said only once its commands drive); an undeclared one that
has not answered within FIRST_ANSWER_WAIT is taken for free too: a timer on simulated time cannot answer before time
moves on. All this only over DDS (`over_dds`): in one process (the headless trials) no step is lost in transit, and
a controller that has not answered yet is still computing its answer (a script that loops without stepping is its
time limit's to end).

Two different answers to one step (a second publisher answering by name, or one answering twice, differently) are
a CONFLICT: the first drives, and the run is no longer reproducible (which one came first is a matter of timing).

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
from collections.abc import Callable, Collection, Sequence

import numpy as np

RESEND_AFTER = 1.0
"""Wall seconds a step waits for the first answer of a controller before it is sent again."""
FIRST_ANSWER_WAIT = 10.0
"""Wall seconds an undeclared controller may take to answer for the first time (a loaded machine starting a Python
script) before it is taken for one that does not answer each step (a timer on simulated time waits for time to
move). A declared one is never timed so (`Controller`)."""
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


DECLARATION_TOPIC = '/lockstep_declarations'
"""Where a controller declares, before its first answer, which it is (std_msgs/String, latched): a line
`lockstep TOPIC...` or `own_rate TOPIC...`, TOPIC the fully qualified command topics it publishes (/epuck3/wheel_cmd).
Global, as the topics it names are: one publisher per process, whatever namespaces its robots are in."""
MAX_DECLARATION = 1_000_000
"""Characters a declaration may have (20,000 robots' topics); a longer one is refused."""


class Controller(enum.Enum):
    """What is known of a robot's controller before its first answer: from its declaration, or from the type it
    publishes (the values complete a sentence: "the controller of epuck3 ...")."""

    UNDECLARED = 'did not declare which it is'
    """It may answer by name (a wheel_cmd publisher): waited for at most FIRST_ANSWER_WAIT for its first answer."""
    LOCKSTEP = 'is declared in lockstep'
    """Waited for as long as it takes from the first step."""
    OWN_RATE = f'is declared to answer at its own rate (on {DECLARATION_TOPIC})'
    UNNAMING = 'publishes commands of a type that cannot name a step (plain Twist on cmd_vel, cmd_vel_stamped off)'

    @property
    def free(self) -> bool:
        """Not waited for beyond OWN_RATE_WAIT, from the moment the graph shows it."""
        return self in (Controller.OWN_RATE, Controller.UNNAMING)


DECLARATION_WORDS = {'lockstep': Controller.LOCKSTEP, 'own_rate': Controller.OWN_RATE}
"""The first word of a declaration."""
HOW_TO_DECLARE = (f'a controller says which it is before its first answer on {DECLARATION_TOPIC} (std_msgs/String, '
                  f'transient local): "lockstep TOPIC" or "own_rate TOPIC", TOPIC its fully qualified command topic')


def declaration(controller: Controller, topics: Sequence[str]) -> str:
    """The text of a declaration that the publishers on `topics` are `controller` (LOCKSTEP or OWN_RATE)."""
    word = next(word for word, kind in DECLARATION_WORDS.items() if kind is controller)
    return ' '.join([word, *topics])


def read_declaration(text: str) -> tuple[Controller, list[str]]:
    """A declaration's kind and topics; ValueError saying what is wrong (it comes from anyone on the domain)."""
    if len(text) > MAX_DECLARATION:
        raise ValueError(f'{len(text)} characters, more than {MAX_DECLARATION}')
    words = text.split()
    if not words or words[0] not in DECLARATION_WORDS:
        raise ValueError(f'it must start with {" or ".join(DECLARATION_WORDS)}, got {text[:40]!r}')
    topics = words[1:]
    if not topics or not all(topic.startswith('/') for topic in topics):
        raise ValueError('it must name fully qualified topics (/epuck3/wheel_cmd)')
    return DECLARATION_WORDS[words[0]], topics


class Answer(enum.Enum):
    """What an answer is to the current step (`Lockstep.classify`)."""

    STEP = 'answers the current step, naming it'
    UNSTAMPED = 'sends commands that name no step'
    BESIDE = 'names no step, beside a controller that answers by name'
    """Another publisher on the robot's commands (a teleop, the view), or its controller's last stop: it drives,
    and answers nothing."""
    STALE = 'answered with a command naming an older step than the current one'
    REPEATED = 'answers a step it has answered already'
    """The same command again (a step sent again, answered twice): dropped."""
    CONFLICT = 'answers a step it has answered already, differently'
    """Two answers to one step that differ (another publisher, or one that answers twice): the first drives."""
    FUTURE = 'names a step the simulation has not reached'
    SILENT = f'did not answer its first step within {FIRST_ANSWER_WAIT:g} s, and did not declare which it is'


class StepClaimError(RuntimeError):
    """A thread stepped without holding the claim."""


def _every_robot(robots: int) -> Callable[[], Collection[int]]:
    return lambda: range(robots)


class Lockstep:
    """The answers to the current step of `robots` robots, and the one right to step (see the module)."""

    def __init__(self, robots: int, step: StepFunction, timeout: float = 0.0,
                 driven: Callable[[], Collection[int]] | None = None, lend: Callable[[], bool] = lambda: False,
                 on_stall: Callable[[Sequence[int], float, Sequence[int]], None] = lambda robots, waited, gone: None,
                 on_resend: Callable[[Sequence[int]], None] = lambda back: None,
                 on_free: Callable[[int, Answer | Controller], None] = lambda robot, why: None,
                 on_timeout: Callable[[Sequence[int]], None] = lambda robots: None, over_dds: bool = True,
                 controller: Callable[[int], Controller] = lambda robot: Controller.UNDECLARED,
                 on_leave: Callable[[int], None] = lambda robot: None) -> None:
        """`timeout`: wall seconds a step waits for the answers of controllers in lockstep, 0 = as long as it takes;
        `driven()`: the robots that have a controller on the graph now (default: all); `lend()`: whether the thread of a
        step's last answer takes the next step (asked under the condition while the holder waits, so nothing the holder
        writes changes meanwhile); `on_stall(robots, waited, gone)`: every STALL_REPORT while a step waits for them,
        `waited` wall seconds since it first went out, `gone` those of them whose controller left the graph;
        `on_resend(back)`: the step is about to be sent again (`back`: for these robots, whose controller is back on the
        graph; else for a first answer); `on_free(robot, why)`: that robot's controller is free from now on, for what
        its answer was or what it is; `on_timeout(robots)`: the step goes on without their answers; `over_dds`: steps
        and answers travel over DDS (resends and the first answer's wait, see the module); `controller(robot)`: what is
        known of a driven robot's controller before its first answer (and of one that left the graph: OWN_RATE is its
        goodbye); `on_leave(robot)`: that robot's controller left, declared at its own rate: no longer waited for."""
        self._robots = robots
        self._step = step
        self._timeout = timeout if timeout > 0.0 else math.inf
        self._driven = driven or _every_robot(robots)
        self._lend = lend
        self._on_stall, self._on_resend, self._on_free, self._on_timeout = on_stall, on_resend, on_free, on_timeout
        self._over_dds = over_dds
        self._controller, self._on_leave = controller, on_leave
        self._holder: int | None = None
        """The thread (ident) that may step now."""
        self._changed = threading.Condition()
        """Guards everything below; notified when the answers the holder waits for are in."""
        self._init_answers(robots)
        self._parked = False
        """The holder waits for the current step's answers (`await_answers`)."""
        self._started = self._deadline = self._own_rate_deadline = 0.0
        """When the step was last sent (again), its time-out, and how long free controllers are waited for."""
        self._sent = 0.0
        """When the current step first went out (monotonic s): a stall is measured from it."""
        self._stall_reports = 0
        """Stall lines said for the current step."""
        self._required = 0
        """Controllers to be connected before the next step (`require_controllers`); 0 once they were."""
        self._closed = False

    def _init_answers(self, robots: int) -> None:
        """What is known of each robot's answers and controller: none answered, nobody in lockstep yet."""
        self._answered: list[int] = []
        """The robots an answer to the current step came from (one may be there twice)."""
        self._never_answered = set(range(robots))
        """Robots no answer has come from yet."""
        self._free: set[int] = set()
        """Robots whose controller does not answer each step (see the module): waited for at most OWN_RATE_WAIT."""
        self._first_awaited: dict[int, float] = {}
        """When each robot that never answered was first awaited (monotonic s): FIRST_ANSWER_WAIT counts from it."""
        self._last_named = np.zeros(robots, dtype=np.int64)
        """The step (ns) the robot's last named answer named, where `_named`: a second answer to it is a repeat or a
        conflict."""
        self._named = np.zeros(robots, dtype=bool)
        self._last_command: dict[int, object] = {}
        """The command of that answer, where it was not None and not one of the last `answer_all`'s: a second answer
        to the step with another is a conflict."""
        self._from_batch = np.zeros(robots, dtype=bool)
        """The robots whose last answer came with the last `answer_all`: their command is `_batch_command(robot)`."""
        self._batch_command: Callable[[int], object] = lambda robot: None
        self._kinds: dict[int, Controller] = {}
        """What the graph said last of each driven robot that never answered (`controller`)."""
        self._members: set[int] = set()
        """Robots in lockstep: their controller answered by name, and is not free."""
        self._gone: set[int] = set()
        """Robots in lockstep whose controller is no longer on the graph."""
        self._back: set[int] = set()
        """Robots of `_gone` whose controller is on the graph again: the current step is to be sent again."""
        self._awaited: set[int] = set()
        """Robots in lockstep (or not yet answered) whose answer to the current step is still awaited."""
        self._free_awaited: set[int] = set()
        """Free robots that have not answered the current step: waited for until `_own_rate_deadline`."""

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
                driven = sorted(self._driven())
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
                self._answered = []
                self._sent, self._stall_reports = time.monotonic(), 0
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

    def last_answer(self, robot: int) -> tuple[int | None, object]:
        """The step (ns) `robot`'s last named answer named, and its command (what a conflict is told from)."""
        with self._changed:
            return self._named_by(robot), self._command_of(robot)

    def _command_of(self, robot: int) -> object:
        return self._batch_command(robot) if self._from_batch[robot] else self._last_command.get(robot)

    def _named_by(self, robot: int) -> int | None:
        return int(self._last_named[robot]) if self._named[robot] else None

    def classify(self, robot: int, named: int | None, current: int, command: object = None) -> Answer:
        """What an answer of `robot` naming step `named` (ns; None: it names none) with `command` (anything that
        compares equal for the same command) is while step `current` (ns) is out. A repeat (a step sent again,
        answered twice), a conflict (a second answer to a step, or to an older one than the robot answered, that is
        not the same command) and a step not reached yet are the caller's to drop; the others drive, and all but
        BESIDE answer (`answer`)."""
        with self._changed:
            last = self._named_by(robot)
            if named is None:
                return Answer.BESIDE if last is not None else Answer.UNSTAMPED
            if named == last:
                return Answer.REPEATED if command == self._command_of(robot) else Answer.CONFLICT
            if last is not None and named < last:
                return Answer.CONFLICT
            if named > current:
                return Answer.FUTURE
            return Answer.STEP if named == current else Answer.STALE

    def answer(self, robot: int, kind: Answer = Answer.STEP, named: int | None = None, command: object = None) -> None:
        """An answer of `robot` (`kind`: `classify`'s verdict, STEP, STALE or UNSTAMPED; `named`: the step it names;
        `command`: what it commands, as given to `classify`) was applied. If it was the step's last awaited answer and
        the holder, waiting, lends its claim, the next step is taken here, in the calling thread."""
        with self._changed:
            if named is not None:
                self._last_named[robot], self._named[robot] = named, True
                self._from_batch[robot] = False
                if command is None:
                    self._last_command.pop(robot, None)
                else:
                    self._last_command[robot] = command
            if kind is not Answer.STEP:
                self._make_free(robot, kind)
            self._answered.append(robot)
            self._awaited.discard(robot)
            self._free_awaited.discard(robot)
            self._after_answers()

    def answers_step(self, robots: np.ndarray, named: int, current: int) -> bool:
        """Whether `classify` says STEP of an answer naming `named` (ns, without a command) of each of `robots` (an
        array of robot indices) while step `current` is out: one NumPy look for a swarm's answers to a step."""
        with self._changed:
            return named == current and not (self._named[robots] & (self._last_named[robots] >= named)).any()

    def answer_all(self, robots: np.ndarray, named: int,
                   command_of: Callable[[int], object] = lambda robot: None) -> None:
        """`answer(robot, Answer.STEP, named, command_of(robot))` of each of `robots` (an array of robot indices,
        each distinct), whose answers `answers_step` found to answer the current step, at once: `command_of` is asked
        only if a robot's answer is compared with another (a swarm's whole answer sent again is a repeat, robot by
        robot). The step's last answer may take the next step here, as in `answer`."""
        with self._changed:
            self._keep_batch_commands(robots)
            self._last_named[robots], self._named[robots], self._from_batch[robots] = named, True, True
            self._batch_command = command_of
            listed = robots.tolist()
            self._answered += listed
            self._awaited.difference_update(listed)
            self._free_awaited.difference_update(listed)
            self._after_answers()

    def _keep_batch_commands(self, robots: np.ndarray) -> None:
        """Before `answer_all` of `robots`: the last one's commands of robots not among them, kept one by one (none
        in a swarm's run: each answer names the same robots); `robots`' own are the new answers'."""
        self._from_batch[robots] = False
        for robot in np.flatnonzero(self._from_batch).tolist():
            command = self._batch_command(robot)
            if command is not None:
                self._last_command[robot] = command
        self._from_batch[:] = False
        for robot in robots.tolist() if self._last_command else ():
            self._last_command.pop(robot, None)

    def _after_answers(self) -> None:
        """Under the condition, answers just noted: wake the holder once the awaited ones are in, or take the next
        step here if it lends its claim."""
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
            if self._back:   # a controller that had left is back: it may have missed the step
                self._on_resend(sorted(self._back))
                self._back.clear()
                return False
            unanswered = sorted(self._awaited & self._never_answered) if self._over_dds else []
            for robot in unanswered:
                if self._kinds.get(robot) is Controller.UNDECLARED and \
                        now - self._first_awaited.setdefault(robot, now) >= FIRST_ANSWER_WAIT:
                    self._make_free(robot, Answer.SILENT)
            if unanswered and not self._awaited:
                continue
            if unanswered and now - self._started >= RESEND_AFTER:
                self._on_resend([])
                return False
            next_report = self._sent + STALL_REPORT * (self._stall_reports + 1)
            if self._awaited and now >= next_report:
                self._stall_reports = int((now - self._sent) // STALL_REPORT)   # one line, however late this look
                self._on_stall(sorted(self._awaited), now - self._sent, sorted(self._awaited & self._gone))
                continue
            if self._awaited:
                until = min(self._deadline, next_report, now + GRAPH_POLL,
                            self._started + RESEND_AFTER if unanswered else math.inf)
            else:
                until = self._own_rate_deadline
            if not self._changed.wait(max(0.0, until - now)):
                self._read_graph()

    def _make_free(self, robot: int, why: Answer | Controller) -> None:
        """From now on `robot`'s controller is not waited for beyond OWN_RATE_WAIT (said once)."""
        if robot not in self._free:
            self._free.add(robot)
            self._members.discard(robot)
            self._gone.discard(robot)
            self._awaited.discard(robot)
            self._on_free(robot, why)

    def _expect(self) -> None:
        """A step is out: wait for its answers from now on."""
        now = time.monotonic()
        self._started = now
        self._deadline, self._own_rate_deadline = now + self._timeout, now + OWN_RATE_WAIT
        self._read_graph()

    def _read_graph(self) -> None:
        """Which robots' answers the current step waits for: those with a controller on the graph, and those in
        lockstep whose controller left it (see the module); free ones at most OWN_RATE_WAIT."""
        driven = set(self._driven())
        for robot in self._gone - driven:
            if self._controller(robot) is Controller.OWN_RATE:   # its goodbye: it left on purpose
                self._members.discard(robot)
                self._on_leave(robot)
        members = self._members
        gone = members - driven
        self._back |= (self._gone - gone) & driven
        self._gone = gone
        free = set()
        for robot in driven - members:
            if robot in self._never_answered and robot not in self._free:
                self._kinds[robot] = kind = self._controller(robot)
                if kind.free:
                    free.add(robot)
        waiting = (driven | members).difference(self._answered)
        self._free_awaited = waiting & (self._free | free)
        self._awaited = waiting - self._free_awaited

    def _take_answers(self) -> None:
        """The current step is answered: note who answered, and clear the answers, so that no thread takes them
        for the next step's."""
        answered = self._answered
        if self._never_answered:
            self._never_answered.difference_update(answered)
        self._members.update(answered)
        self._members -= self._free   # (`_make_free` takes a robot out of them)
        self._answered = []
        self._awaited, self._free_awaited = set(), set()
        self._back.clear()   # whoever came back has answered
