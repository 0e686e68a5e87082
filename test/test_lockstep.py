"""`Lockstep` on its own: no ROS, no DDS; the answers come from test threads as they would from an executor.

Timeouts are short and nothing asserts on how long anything took: only on what was stepped, and by which thread.
A wait that would last for ever is ended by `close` from another thread (a test never waits out a real stall)."""
from __future__ import annotations

import threading

import numpy as np
import pytest

import epuck_ros.lockstep as lockstep_module
from epuck_ros.lockstep import (MAX_DECLARATION, Answer, Controller, Lockstep, StepClaimError, declaration,
                                read_declaration)

SHORT = 0.02
"""A timeout that expires quickly."""
LONG = 30.0
"""A timeout no passing test waits out."""


class Sim:
    """Records the steps it is asked for: (step number, resend, thread name)."""

    def __init__(self) -> None:
        self.steps: list[tuple[int, bool, str]] = []
        self.count = 0

    def __call__(self, resend: bool) -> None:
        self.count += 0 if resend else 1
        self.steps.append((self.count, resend, threading.current_thread().name))


def lockstep(robots: int = 2, timeout: float = LONG, **kwargs: object) -> tuple[Lockstep, Sim]:
    sim = Sim()
    step = Lockstep(robots, sim, timeout, **kwargs)
    step.claim()
    return step, sim


def in_thread(target: object, name: str = 'answers') -> threading.Thread:
    thread = threading.Thread(target=target, name=name)
    thread.start()
    return thread


def test_a_step_waits_for_every_driven_robot_and_only_for_them():
    step, sim = lockstep(robots=3, driven=lambda: [0, 2])
    step.step()
    step.answer(0)
    step.answer(1)   # nobody drives robot 1: its answer counts for nothing
    answers = in_thread(lambda: step.answer(2))
    assert step.await_answers()
    answers.join()
    step.step()
    assert [count for count, _, _ in sim.steps] == [1, 2]


def test_a_controller_that_never_answered_gets_its_step_again_until_it_answers(monkeypatch):
    """It may have subscribed after the step went out: the step is sent again every RESEND_AFTER, with no limit."""
    monkeypatch.setattr(lockstep_module, 'RESEND_AFTER', SHORT)
    step, sim = lockstep(robots=2, timeout=0.0)
    step.step()
    step.answer(0)
    outcomes = []
    for _ in range(5):
        outcomes.append(step.await_answers())
        step.step(resend=True)
    step.answer(1)
    outcomes.append(step.await_answers())
    assert outcomes == [False] * 5 + [True]
    assert [(count, resend) for count, resend, _ in sim.steps] == [(1, False)] + [(1, True)] * 5


def test_in_one_process_a_first_answer_is_waited_for_without_resends_or_giving_up(monkeypatch):
    """Headless (over_dds=False) no step is lost in transit: a controller still computing its first answer is
    neither sent the step again nor taken for a free one, however long it takes (here 10 times both waits)."""
    monkeypatch.setattr(lockstep_module, 'RESEND_AFTER', SHORT)
    monkeypatch.setattr(lockstep_module, 'FIRST_ANSWER_WAIT', SHORT)
    freed = []
    step, sim = lockstep(robots=1, timeout=0.0, over_dds=False, on_free=lambda robot, why: freed.append(robot))
    step.step()
    answering = threading.Timer(10 * SHORT, step.answer, args=(0,))
    answering.start()
    assert step.await_answers() is True
    answering.join()
    assert [(count, resend) for count, resend, _ in sim.steps] == [(1, False)] and freed == []


def test_a_stalled_controller_in_lockstep_is_waited_for_as_long_as_it_takes_and_reported(monkeypatch):
    """No time-out unless the user sets one: a line every STALL_REPORT names the robot and how long."""
    monkeypatch.setattr(lockstep_module, 'STALL_REPORT', SHORT)
    stalls: list[tuple[list[int], float]] = []
    step, sim = lockstep(robots=2, timeout=0.0,
                         on_stall=lambda robots, waited, gone: stalls.append((list(robots), waited)))
    step.step()
    step.answer(0)
    step.answer(1)
    assert step.await_answers()
    step.step()
    step.answer(0)   # robot 1 stalls

    def answer_late() -> None:
        while len(stalls) < 3:
            threading.Event().wait(SHORT)
        step.answer(1, Answer.STEP)

    late = in_thread(answer_late)
    assert step.await_answers()
    late.join()
    assert [robots for robots, _ in stalls[:3]] == [[1]] * 3
    assert [waited for _, waited in stalls[:3]] == sorted(waited for _, waited in stalls[:3])
    assert len(sim.steps) == 2


def test_a_timeout_the_user_set_passes_the_step_and_says_whose_answer_was_missing():
    timed_out = []
    step, _ = lockstep(robots=2, timeout=SHORT, on_timeout=lambda robots: timed_out.append(list(robots)))
    step.step()
    step.answer(0)
    step.answer(1)
    assert step.await_answers()
    step.step()
    step.answer(0)
    assert step.await_answers()   # robot 1 answered before: nothing to send again, the step goes on
    assert timed_out == [[1]]


def test_with_no_controller_nobody_is_waited_for():
    step, _ = lockstep(robots=3, timeout=0.0, driven=lambda: [])
    step.step()
    assert step.await_answers()


def test_an_answer_before_the_step_does_not_answer_it():
    timed_out = []
    step, _ = lockstep(robots=1, timeout=SHORT, on_timeout=timed_out.append)
    step.step()
    step.answer(0)
    assert step.await_answers()
    step.answer(0)                # early: the next step is not out yet
    step.step()
    assert step.await_answers()   # ... so this one timed out
    assert timed_out == [[0]]


def _robot_by_robot(step: Lockstep) -> None:
    step.answer(0)
    step.answer(1)      # the first step's last answer: the second step is taken here
    step.answer(0)
    step.answer(1)      # and the third


def _a_swarm_at_once(step: Lockstep) -> None:
    step.answer_all(np.array([2, 0, 1]), 0)   # the first step's answers: the second step is taken here
    step.answer_all(np.array([0, 1]), 32)
    step.answer(2, Answer.STEP, 32)           # robot by robot completes it as well: the third step


@pytest.mark.parametrize('robots, answer', [(2, _robot_by_robot), (3, _a_swarm_at_once)])
def test_the_thread_of_the_last_answer_steps_while_the_holder_lends_its_claim(robots, answer):
    """The last answer to a step, robot by robot (`answer`) or a swarm's noted at once (`answer_all`), takes the
    next step in its own thread while the holder lends its claim."""
    waiting = threading.Event()   # set when the holder reads who is driven, under the lock it releases only to wait
    sim = Sim()
    step = Lockstep(robots, sim, LONG, driven=lambda: waiting.set() or list(range(robots)), lend=lambda: True)

    def holder() -> None:
        step.claim()
        step.step()
        step.await_answers()

    def answers() -> None:
        waiting.wait()
        answer(step)

    holding = in_thread(holder, 'holder')
    in_thread(answers).join()
    step.close()
    holding.join()
    assert [(count, thread) for count, _, thread in sim.steps] == [(1, 'holder'), (2, 'answers'), (3, 'answers')]


def test_the_holder_steps_itself_when_it_does_not_lend_its_claim():
    step, sim = lockstep(robots=1, lend=lambda: False)
    step.step()
    answers = in_thread(lambda: step.answer(0))
    assert step.await_answers()
    answers.join()
    step.step()
    assert [thread for _, _, thread in sim.steps] == ['MainThread', 'MainThread']


def test_only_the_holder_of_the_claim_may_step_or_wait():
    step, sim = lockstep(robots=1)
    errors = []

    def intruder() -> None:
        for attempt in (step.step, step.await_answers):
            try:
                attempt()
            except StepClaimError as error:
                errors.append(str(error))

    in_thread(intruder, 'intruder').join()
    assert len(errors) == 2 and all('intruder' in error for error in errors)
    assert sim.steps == []
    step.step()   # the holder still may
    assert len(sim.steps) == 1


def test_answers_outside_a_wait_never_step():
    """Not waiting (paced, paused), the holder lends nothing: an answer does not step, whatever `lend` says."""
    step, sim = lockstep(robots=1, lend=lambda: True)
    step.step()
    step.answer(0)
    assert len(sim.steps) == 1


@pytest.mark.parametrize('kind', [Answer.UNSTAMPED, Answer.STALE])
def test_a_controller_is_free_by_what_it_sends_and_is_then_no_longer_waited_for(kind):
    """Answers that name no step, or an older step: a timer or a joystick, not a lockstep controller. Said once;
    from then on each step waits at most OWN_RATE_WAIT for it (with no time-out set, a step would otherwise wait
    for ever)."""
    found = []
    step, sim = lockstep(robots=2, timeout=0.0, on_free=lambda robot, answer: found.append((robot, answer)))
    step.step()
    step.answer(0)
    step.answer(1, kind)
    assert step.await_answers()
    for _ in range(3):   # robot 1 answers no more
        step.step()
        step.answer(0)
        assert step.await_answers()
    assert found == [(1, kind)]
    assert len(sim.steps) == 4 and not any(resend for _, resend, _ in sim.steps)


def test_answers_are_paired_with_the_step_they_name():
    step, _ = lockstep(robots=2)
    assert step.classify(0, None, 64) is Answer.UNSTAMPED
    assert step.classify(0, 64, 64) is Answer.STEP
    assert step.classify(0, 32, 64) is Answer.STALE
    assert step.classify(0, 96, 64) is Answer.FUTURE
    step.step()
    step.answer(0, Answer.STEP, 64)
    assert step.classify(0, 64, 64) is Answer.REPEATED      # the step sent again, answered twice
    assert step.classify(0, 64, 96) is Answer.REPEATED      # ... the second answer come after the next step
    assert step.classify(0, None, 96) is Answer.BESIDE      # a stop, or another publisher, beside a named answer
    assert step.classify(1, 64, 64) is Answer.STEP          # each robot on its own


def test_a_resend_publishes_the_same_step_again_keeps_its_answers_and_says_so(monkeypatch):
    monkeypatch.setattr(lockstep_module, 'RESEND_AFTER', SHORT)
    resent = []
    step, sim = lockstep(robots=2, timeout=0.0, on_resend=lambda back: resent.append(sim.count))
    step.step()
    step.answer(0)
    assert not step.await_answers()
    step.step(resend=True)
    step.answer(1)     # robot 0's answer to the first sending still counts: its repeat would be dropped
    assert step.await_answers()
    assert resent == [1]
    assert [(count, resend) for count, resend, _ in sim.steps] == [(1, False), (1, True)]


def test_the_first_step_waits_until_the_required_controllers_are_connected(monkeypatch):
    """Whoever resumes saw the controllers before the simulator's matching did: stepping at once would start the
    late ones a few steps behind."""
    monkeypatch.setattr(lockstep_module, 'CONTROLLERS_REPORT', 0.0)
    connected: list[int] = []
    reports: list[tuple[int, list[int]]] = []
    step, sim = lockstep(robots=3, driven=lambda: list(connected))
    step.require_controllers(2)

    def connect() -> None:
        while not reports:    # reported while still short of controllers
            threading.Event().wait(SHORT)
        connected.extend([0, 2])

    connecting = in_thread(connect)
    assert step.await_controllers(lambda: True, lambda required, driven: reports.append((required, list(driven))))
    connecting.join()
    assert reports[0] == (2, [])
    connected.clear()             # met once: a controller that leaves later holds no step up
    assert step.await_controllers(lambda: True, lambda *_: pytest.fail('no wait once met'))
    assert sim.steps == []        # waiting never steps


def test_a_wait_for_controllers_ends_when_asked_or_closed():
    step, _ = lockstep(robots=1, driven=lambda: [])
    step.require_controllers(1)
    assert not step.await_controllers(lambda: False, lambda *_: None)   # paused meanwhile, say
    threading.Timer(SHORT, step.close).start()
    assert not step.await_controllers(lambda: True, lambda *_: None)


def test_no_step_is_lent_while_controllers_are_required():
    """A last answer never takes the next step in its thread while the simulator still waits for controllers."""
    waiting = threading.Event()   # as in the lending test: the holder is parked once the answer gets the lock
    sim = Sim()
    step = Lockstep(2, sim, LONG, driven=lambda: waiting.set() or [0], lend=lambda: True)
    step.claim()
    step.step()
    step.require_controllers(2)

    def answer() -> None:
        waiting.wait()
        step.answer(0)

    answers = in_thread(answer)
    assert step.await_answers()
    answers.join()
    assert [(count, thread) for count, _, thread in sim.steps] == [(1, 'MainThread')]


def test_close_ends_a_wait_without_answers():
    step, _ = lockstep(robots=1, timeout=0.0)
    step.step()
    closer = threading.Timer(SHORT, step.close)
    closer.start()
    assert step.await_answers()   # closed: go on (the loop then sees it must end)
    closer.join()


@pytest.mark.parametrize('robots', [1, 3])
def test_a_headless_loop_steps_once_per_round_of_answers(robots):
    """The trial runner's use: one thread answers for every robot, then waits (at once) and steps."""
    step, sim = lockstep(robots=robots, timeout=0.0)
    step.step()
    for _ in range(5):
        for robot in range(robots):
            step.answer(robot)
        assert step.await_answers()
        step.step()
    assert [count for count, _, _ in sim.steps] == list(range(1, 7))


def test_answers_from_several_threads_step_each_step_once():
    """Each robot's answers from its own thread (as from a multi-threaded executor): every step is taken once, by
    the thread of its last answer, after every robot answered the one before."""
    robots, rounds = 4, 50
    published = threading.Condition()
    sim = Sim()

    def take(resend: bool) -> None:
        with published:
            sim(resend)
            published.notify_all()

    step = Lockstep(robots, take, LONG, lend=lambda: True)
    ending = threading.Event()

    def loop() -> None:   # as the sim's loop thread: step, wait for the answers (lending the claim), again
        step.claim()
        step.step()
        while True:
            step.await_answers()
            if ending.is_set():
                return
            step.step()

    def answer_each_step(robot: int) -> None:
        for number in range(1, rounds + 1):
            with published:
                assert published.wait_for(lambda: sim.count >= number, timeout=LONG)
            step.answer(robot)

    holder = in_thread(loop, 'holder')
    answerers = [in_thread(lambda robot=robot: answer_each_step(robot), f'robot{robot}') for robot in range(robots)]
    for thread in answerers:
        thread.join()
    with published:
        assert published.wait_for(lambda: sim.count == rounds + 1, timeout=LONG)
    ending.set()
    step.close()
    holder.join()
    assert [count for count, _, _ in sim.steps] == list(range(1, rounds + 2))
    assert {thread for _, _, thread in sim.steps[1:]} <= {'holder'} | {f'robot{robot}' for robot in range(robots)}


class FakeClock:
    """lockstep's `time`: monotonic seconds that move only when a test says (what a stall line measures)."""

    def __init__(self) -> None:
        self.now = 1000.0

    def monotonic(self) -> float:
        return self.now


def test_a_stall_line_measures_the_stall_not_the_time_since_the_holder_began_to_wait(monkeypatch):
    """Issue 33 item 5: lent steps, each answered within a (fake) second, for 20 s: the holder, waiting all along,
    said "has waited 0 s" once 5 s had passed since it began. A line comes once a step has waited STALL_REPORT since
    it first went out, and says how long, once per STALL_REPORT however late the holder looks."""
    clock = FakeClock()
    monkeypatch.setattr(lockstep_module, 'time', clock)
    looked = threading.Semaphore(0)   # released each time the graph is read: by the parked holder or a lent step
    stalls: list[tuple[list[int], float]] = []
    sim = Sim()
    step = Lockstep(1, sim, 0.0, driven=lambda: looked.release() or [0], lend=lambda: True,
                    on_stall=lambda robots, waited, gone: stalls.append((list(robots), waited)))

    def holder() -> None:
        step.claim()
        step.step()
        step.await_answers()

    holding = in_thread(holder, 'holder')
    for _ in range(20):
        assert looked.acquire(timeout=LONG)   # the holder is parked (or the last answer's step was taken)
        clock.now += 1.0
        step.answer(0)                        # a lent step, answered a second after it went out
    for _ in range(3):                        # the holder looks again, 20 s after it began to wait
        assert looked.acquire(timeout=LONG)
    assert stalls == []
    clock.now += 12.0                         # now the 21st step stalls
    for _ in range(3):
        assert looked.acquire(timeout=LONG)
    step.close()
    holding.join()
    assert stalls == [([0], 12.0)]
    assert len(sim.steps) == 21


def test_a_robot_in_lockstep_whose_controller_left_the_graph_is_waited_for_and_sent_its_step_again_when_back(
        monkeypatch):
    """Issue 33 item 4: a controller stopped (SIGSTOP), frozen or crashed leaves the graph only once DDS drops it;
    the robot was then undriven, and the run went on, called reproducible. Its robot is waited for as long as it
    takes (the stall line says its controller left), and when a controller of it is back, the step goes out again:
    it may have missed it."""
    monkeypatch.setattr(lockstep_module, 'STALL_REPORT', SHORT)
    on_graph = [0, 1]
    stalls: list[tuple[list[int], list[int]]] = []
    resent = []
    step, sim = lockstep(robots=2, timeout=0.0, driven=lambda: list(on_graph), on_resend=resent.append,
                         on_stall=lambda robots, waited, gone: stalls.append((list(robots), list(gone))))
    step.step()
    step.answer(0)
    step.answer(1)
    assert step.await_answers()
    step.step()
    step.answer(1)
    on_graph.remove(0)

    def come_back() -> None:
        while len(stalls) < 2:
            threading.Event().wait(SHORT)
        on_graph.append(0)

    back = in_thread(come_back)
    assert step.await_answers() is False
    back.join()
    assert stalls[:2] == [([0], [0])] * 2 and resent == [[0]]
    step.step(resend=True)
    step.answer(0)
    assert step.await_answers()
    assert [(count, resend) for count, resend, _ in sim.steps] == [(1, False), (2, False), (2, True)]


def test_a_second_answer_to_a_step_is_a_repeat_only_with_the_same_command():
    """Issue 33 item 3: a second answer to a step was dropped as a repeat, whatever it said, whoever sent it: a second
    controller answering by name took a robot over, silently. One that differs is a conflict (the caller breaks the
    run); so is an answer to a step older than one the robot answered."""
    step, _ = lockstep(robots=1)
    step.step()
    step.answer(0, Answer.STEP, 64, ('/wheel_cmd', 1.0, 1.0))
    assert step.classify(0, 64, 64, ('/wheel_cmd', 1.0, 1.0)) is Answer.REPEATED
    assert step.classify(0, 64, 64, ('/wheel_cmd', 2.0, 1.0)) is Answer.CONFLICT
    assert step.classify(0, 64, 64, ('/cmd_vel', 1.0, 1.0)) is Answer.CONFLICT
    assert step.classify(0, 64, 96, ('/wheel_cmd', 2.0, 1.0)) is Answer.CONFLICT   # come after the next step
    assert step.classify(0, 32, 96, ('/wheel_cmd', 1.0, 1.0)) is Answer.CONFLICT   # older than one it answered
    assert step.last_answer(0) == (64, ('/wheel_cmd', 1.0, 1.0))


@pytest.mark.parametrize('kind', [Controller.UNNAMING, Controller.OWN_RATE])
def test_a_controller_that_cannot_or_says_it_will_not_answer_by_name_is_not_waited_for_from_the_start(
        monkeypatch, kind):
    """Issue 33 item 6: a plain Twist publisher (or one declared at its own rate) held the first step 10 s
    (FIRST_ANSWER_WAIT), the step sent again every second. It is free from the moment the graph shows it; the run
    breaks only once its commands drive."""
    monkeypatch.setattr(lockstep_module, 'RESEND_AFTER', SHORT)
    freed: list[tuple[int, object]] = []
    resent = []
    step, sim = lockstep(robots=2, timeout=0.0, on_resend=resent.append,
                         on_free=lambda robot, why: freed.append((robot, why)),
                         controller=lambda robot: kind if robot == 1 else Controller.LOCKSTEP)
    for _ in range(3):
        step.step()
        step.answer(0)
        assert step.await_answers()
    assert resent == [] and freed == []
    step.step()
    step.answer(0)
    step.answer(1, Answer.UNSTAMPED)
    assert step.await_answers()
    assert freed == [(1, Answer.UNSTAMPED)] and resent == []
    assert len(sim.steps) == 4


@pytest.mark.parametrize('kind, freed_as', [(Controller.LOCKSTEP, []), (Controller.UNDECLARED, [Answer.SILENT])])
def test_only_an_undeclared_controller_is_timed_for_its_first_answer(monkeypatch, kind, freed_as):
    """A controller declared in lockstep is sent its first step again until it answers, as long as it takes (here
    ten times FIRST_ANSWER_WAIT); an undeclared one is taken to answer at its own rate after FIRST_ANSWER_WAIT."""
    monkeypatch.setattr(lockstep_module, 'RESEND_AFTER', SHORT)
    monkeypatch.setattr(lockstep_module, 'FIRST_ANSWER_WAIT', 3 * SHORT)
    freed: list[object] = []
    step, _ = lockstep(robots=1, timeout=0.0, on_free=lambda robot, why: freed.append(why),
                       controller=lambda robot: kind)
    step.step()
    deadline = threading.Event()
    threading.Timer(30 * SHORT, deadline.set).start()
    answered = False
    while not answered and not deadline.is_set():
        answered = step.await_answers()
        step.step(resend=not answered)
    assert answered is (kind is Controller.UNDECLARED)
    assert freed == freed_as
    if not answered:
        step.answer(0)
        assert step.await_answers()


def test_a_declaration_names_the_kind_and_the_topics_and_anything_else_is_refused():
    text = declaration(Controller.LOCKSTEP, ['/epuck0/wheel_cmd', '/epuck1/wheel_cmd'])
    assert text == 'lockstep /epuck0/wheel_cmd /epuck1/wheel_cmd'
    assert read_declaration(text) == (Controller.LOCKSTEP, ['/epuck0/wheel_cmd', '/epuck1/wheel_cmd'])
    assert read_declaration(' own_rate  /wheel_cmd\n') == (Controller.OWN_RATE, ['/wheel_cmd'])
    for bad in ['', 'lockstep', 'maybe /wheel_cmd', 'lockstep wheel_cmd', 'lockstep ' + '/w' * MAX_DECLARATION]:
        with pytest.raises(ValueError):
            read_declaration(bad)


def test_a_controller_that_leaves_declared_at_its_own_rate_is_no_longer_waited_for(monkeypatch):
    """Its goodbye: a controller that ends on purpose while the simulation runs declares its own rate, then leaves;
    its robot is waited for until the simulator has both seen it leave and read the goodbye, in either order."""
    monkeypatch.setattr(lockstep_module, 'STALL_REPORT', SHORT)
    on_graph = [0, 1]
    declared = {0: Controller.LOCKSTEP, 1: Controller.LOCKSTEP}
    gone: list[list[int]] = []
    left: list[int] = []
    resent: list[list[int]] = []
    step, sim = lockstep(robots=2, timeout=0.0, driven=lambda: list(on_graph), controller=declared.__getitem__,
                         on_leave=left.append, on_stall=lambda robots, waited, away: gone.append(list(away)),
                         on_resend=resent.append)
    step.step()
    step.answer(0)
    step.answer(1)
    assert step.await_answers()
    step.step()
    on_graph.remove(0)

    def say_goodbye() -> None:
        while [0] not in gone:   # seen gone (and waited for) before the goodbye is read
            threading.Event().wait(SHORT)
        declared[0] = Controller.OWN_RATE
        while not left:
            threading.Event().wait(SHORT)
        step.answer(1)           # the step's other answer comes after

    goodbye = in_thread(say_goodbye)
    assert step.await_answers()
    goodbye.join()
    assert left == [0]
    step.step()
    step.answer(1)
    assert step.await_answers()
    assert len(sim.steps) == 3 and resent == []   # not "back": it left


# --- a swarm's answers at once (`answers_step`, `answer_all`) ---------------------------------------------------------

def test_answers_step_says_step_exactly_when_classify_says_it_of_every_robot():
    """The one NumPy look at a swarm's answers agrees with `classify` robot by robot, whatever each robot answered
    before: none, this step, an older one, a newer one (a conflict), or a per-robot command."""
    step, _ = lockstep(robots=4)
    step.step()
    step.answer(1, Answer.STEP, 32)                               # an older step
    step.answer(2, Answer.STEP, 64, ('/epuck2/wheel_cmd', 1.0, 1.0))   # this step, by its own topic
    step.answer(3, Answer.STEP, 96)                               # a newer one than asked below
    for robots in ([0], [1], [0, 1], [2], [0, 2], [3], [0, 1, 3], [0, 1, 2, 3]):
        for named, current in ((64, 64), (32, 64), (96, 64), (64, 96), (96, 96)):
            robot_by_robot = all(step.classify(robot, named, current) is Answer.STEP for robot in robots)
            assert step.answers_step(np.array(robots), named, current) is robot_by_robot, (robots, named, current)


def test_answer_all_notes_what_answer_notes_robot_by_robot():
    """After `answer_all` each robot's last answer, a repeat of it and a per-robot command it replaced are what the
    same answers one by one leave."""
    by_all, _ = lockstep(robots=3)
    by_one, _ = lockstep(robots=3)
    for step in (by_all, by_one):
        step.step()
        step.answer(1, Answer.STEP, 32, ('/epuck1/wheel_cmd', 1.0, 1.0))
    by_all.answer_all(np.array([0, 1, 2]), 64)
    for robot in range(3):
        by_one.answer(robot, Answer.STEP, 64)
    for robot in range(3):
        assert by_all.last_answer(robot) == by_one.last_answer(robot) == (64, None)
        for named, command in ((64, None), (64, ('/x', 1.0, 1.0)), (32, None), (96, None)):
            assert by_all.classify(robot, named, 96, command) is by_one.classify(robot, named, 96, command)


def test_a_step_waits_for_the_robots_answer_all_did_not_name():
    timed_out: list[list[int]] = []
    step = Lockstep(3, Sim(), SHORT, on_timeout=timed_out.append)
    step.claim()
    step.step()
    step.answer_all(np.array([0, 2]), 0)
    assert step.await_answers()
    assert timed_out == [[1]]   # robot 1's answer was still awaited when the time-out passed the step


def test_a_swarms_answer_sent_again_is_a_repeat_and_a_different_one_a_conflict():
    """`answer_all`'s commands (asked of `command_of` only when compared) are each robot's, as `answer` notes them;
    a later batch of other robots keeps the earlier one's commands for the robots it does not name."""
    step, _ = lockstep(robots=3)
    step.step()
    speeds = {0: 1.0, 1: 2.0, 2: 3.0}
    step.answer_all(np.array([0, 1, 2]), 32, lambda robot: ('/swarm/command', speeds[robot], 0.0))
    assert step.classify(1, 32, 32, ('/swarm/command', 2.0, 0.0)) is Answer.REPEATED
    assert step.classify(1, 32, 32, ('/swarm/command', 2.5, 0.0)) is Answer.CONFLICT
    assert step.last_answer(2) == (32, ('/swarm/command', 3.0, 0.0))
    step.answer_all(np.array([0, 1]), 64, lambda robot: ('/swarm/command', -speeds[robot], 0.0))
    assert step.last_answer(0) == (64, ('/swarm/command', -1.0, 0.0))
    assert step.last_answer(2) == (32, ('/swarm/command', 3.0, 0.0))   # the first batch's, kept
    step.answer(0, Answer.STEP, 96, ('/epuck0/wheel_cmd', 5.0, 5.0))
    assert step.last_answer(0) == (96, ('/epuck0/wheel_cmd', 5.0, 5.0))
    assert step.classify(1, 64, 96, ('/swarm/command', -2.0, 0.0)) is Answer.REPEATED
