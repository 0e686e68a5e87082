"""Webots-style scripts on the pure core, in this process, with no ROS: the same `Robot` and devices as over ROS,
bound to a `CoreLink` instead of to the simulator's topics.

A script steps the world itself (`robot.step()` returns when the next step has happened), while a headless trial
is stepped through one `Lockstep` that waits for every robot's answer to each step (`epuck_ros.experiments.trial.run`,
the order of the sim node in lockstep). A `ScriptStage` joins the two as the sim node joins the simulator and the
controllers' nodes: each robot's script runs in a thread of its own, its `step()` answers the lockstep with the
wheel speeds, and the thread of a step's last answer takes the next step itself (the lockstep lends it the claim,
as the sim node lends it to the thread that receives the last wheel_cmd). A single robot's script thus steps the
world inside its own step() call: no hand-off between threads per step. The trial's loop waits meanwhile, and takes
over when the run reaches its end or a script ends. The run is the lockstep run over ROS, step for step.
"""
from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol

from epuck_ros.behaviours import Observation, WheelCommand
from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_seconds
from epuck_ros.lockstep import Lockstep, StepFunction
from epuck_ros.sensors.turret import Truth
from epuck_ros.simulation import Simulation
from epuck_ros.webots.link import TRUTH, StepData
from epuck_ros.webots.robot import KILL_DELAY, SINGLE_ROBOT_NAME, bind_thread
from epuck_ros.webots.runner import run_script
from epuck_ros.world import TurretDevice


class ScriptRecorder(Protocol):
    """What the scripts of a recorded trial tell its recorder (experiments.recording.TrialRecorder): declared here,
    below the experiments, which import this module."""

    def sense_wanted(self, robot: int, kind: str, sim: Simulation) -> None: ...

    def answered(self, robot: int, left: float, right: float) -> None: ...

    def leds(self, robot: int, values: Sequence[int]) -> None: ...


class ScriptError(RuntimeError):
    """The script ended with an error (raised, or exited with a non-zero code); the message says which."""

    def __init__(self, message: str, code: int = 1) -> None:
        super().__init__(message)
        self.code = code
        """The script's exit code: 2 when the runner refused it in one line (a device its world does not give)."""


class ScriptStage:
    """The scripts of one trial, one per robot (`seats`), and what they share: the simulation, the lockstep they
    answer (`lockstep_for`), and the count of steps taken, which each script's step() waits on."""

    def __init__(self, script: Path, sim: Simulation, over: Callable[[], bool],
                 arguments: tuple[str, ...] = (), recorder: ScriptRecorder | None = None) -> None:
        """`over()`: the run has taken its last step (the simulator pauses there); `recorder` is told what the scripts
        send while it is not (over ROS, what answers the last step may come after the recording stopped)."""
        self.sim, self._over, self._recorder = sim, over, recorder
        self.lockstep: Lockstep | None = None
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)
        """Guards `steps`, `closed` and `failure`; notified, if a script waits, when a step is taken or the run
        closes."""
        self._waiting = 0
        """Scripts waiting for the next step (none while a single robot's thread takes every step itself)."""
        self.steps = 0
        self.closed = False
        """The run is over: every script's step() returns -1 from now on."""
        self.failure: BaseException | None = None
        """What a step taken in a script's thread raised (the recorder's, say): the trial's error, not the script's."""
        self._ended = 0
        """Scripts that have ended: the trial's loop answers for them (wheels still), so no step is lent."""
        self.seats = [ScriptSeat(self, robot, script, arguments) for robot in range(len(sim.names))]

    def lockstep_for(self, publish: StepFunction) -> Lockstep:
        """The trial's lockstep: `publish` takes and publishes a step; the scripts' threads take steps (lent) while
        every script runs and the run is not over, and wait for them, however long, otherwise."""
        def step(resend: bool) -> None:
            publish(resend)
            with self._lock:
                self.steps += 1
                if self._waiting:
                    self._changed.notify_all()

        self.lockstep = Lockstep(len(self.seats), step, timeout=float('inf'), lend=self.lend, over_dds=False)
        return self.lockstep

    def step_after(self, seen: int) -> bool:
        """Wait until step number `seen` is followed by the next (True), or the run is closed (False)."""
        if self.steps != seen:   # taken already (by the calling thread when lent: a single robot's every step)
            return True
        with self._changed:
            self._waiting += 1
            try:
                while self.steps == seen and not self.closed:
                    self._changed.wait()
            finally:
                self._waiting -= 1
            return self.steps != seen

    def lend(self) -> bool:
        """Whether the thread of a step's last answer takes the next step (asked by the lockstep)."""
        return not self._ended and not self._over()

    def answer(self, robot: int, left: float, right: float) -> None:
        """Robot `robot`'s wheel speeds answer the current step; the next step may be taken here (lent)."""
        self.sim.command_wheels(robot, left, right)
        try:
            self.lockstep.answer(robot)
        except BaseException as error:  # noqa: BLE001 - the trial's loop raises it
            with self._changed:
                self.failure, self.closed = error, True
                self._changed.notify_all()
            self.lockstep.close()   # the loop stops waiting for this step's answers

    def recorder(self) -> ScriptRecorder | None:
        """The recorder to tell what a script sends now: None without one, or once the run is over."""
        return None if self._recorder is None or self._over() else self._recorder

    def script_ended(self, robot: int) -> None:
        """Robot `robot`'s script has ended before the run: its wheels stand still from the step it left unanswered
        on (as the simulator's cmd_timeout stops them over ROS), answered by the trial's loop from then on."""
        with self._changed:
            self._ended += 1
            if self.closed:
                return
        self.answer(robot, 0.0, 0.0)   # lends nothing now: the trial's loop wakes and takes the next step

    def close(self) -> None:
        """The end of the simulation: every script's step() returns -1; they have KILL_DELAY s to end (as in Webots),
        then are left behind (daemon threads)."""
        with self._changed:
            self.closed = True
            self._changed.notify_all()
        deadline = time.monotonic() + KILL_DELAY
        for seat in self.seats:
            seat.join(max(0.0, deadline - time.monotonic()))

    def check(self) -> None:
        """Raise what a step taken in a script's thread raised, or ScriptError if a script has ended with an error."""
        if self.failure is not None:
            raise self.failure
        for seat in self.seats:
            seat.check()


class CoreLink:
    """The Robot's link in a headless run: it answers its robot's step to the stage and returns the next one."""

    def __init__(self, stage: ScriptStage, robot: int) -> None:
        self._stage, self._robot = stage, robot
        self._seen = 0
        """The number of the step the script was last handed."""
        self._wanted: set[str] = set()

    def connect(self) -> float:
        return self._stage.sim.time_step

    @property
    def camera_size(self) -> tuple[int, int]:
        """(width, height) of the core's camera images, as SimLink.camera_size over ROS."""
        width, height = self._stage.sim.senses.camera_size
        return width, height

    @property
    def turret(self) -> tuple[TurretDevice, ...]:
        """The devices the world puts in this robot's turret slot (SimLink.turret over ROS)."""
        return self._stage.sim.world.robots[self._robot].turret

    def first_step(self) -> StepData | None:
        return self._step_after(-1)

    def answer_and_wait(self, left: float, right: float) -> StepData | None:
        stage = self._stage
        if stage.closed:
            return None
        recorder = stage.recorder()
        if recorder is not None:
            recorder.answered(self._robot, left, right)
        stage.answer(self._robot, left, right)
        return self._step_after(self._seen)

    def _step_after(self, seen: int) -> StepData | None:
        """The first step after step number `seen` (the robot's answer holds the simulation on it: read it as is);
        None once the run is over."""
        stage = self._stage
        if not stage.step_after(seen):
            return None
        self._seen = stage.steps
        sim, robot = stage.sim, self._robot
        senses = sim.senses
        readings = senses.readings_of(robot) if senses.active else {}
        if TRUTH in self._wanted:   # as the ground_truth topic carries it over ROS
            readings[TRUTH] = Truth.of(sim.true_pose[robot].tolist(), sim.true_twist[robot].tolist())
        return StepData(nanoseconds_from_stamp(*stamp_from_seconds(sim.time)), tuple(sim.wheel_angles[robot].tolist()),
                        tuple(sim.wheel_speeds[robot].tolist()), tuple(sim.ir_raw[robot].tolist()), readings)

    def want(self, kind: str) -> None:
        """A device of sense `kind` was enabled: the core reads that sense for this robot from now on (called inside
        step(), while the simulation waits for this robot's answer); TRUTH (a turret device) is the state itself."""
        if kind not in self._wanted:
            self._wanted.add(kind)
            if kind == TRUTH:
                return
            self._stage.sim.senses.want(kind, [self._robot])
            recorder = self._stage.recorder()
            if recorder is not None:   # the simulator publishes the step in hand at once (its reader waits for it)
                recorder.sense_wanted(self._robot, kind, self._stage.sim)

    def publish_leds(self, values: list[int]) -> None:
        """Into the trial's bag, if it is recorded (no view to tell in a headless run)."""
        recorder = self._stage.recorder()
        if recorder is not None:
            recorder.leds(self._robot, values)

    def close(self) -> None:
        """Nothing to release: no node, no sockets."""


class ScriptSeat:
    """Robot `robot`'s controller in the trial's loop: a Webots-style script in a thread of its own, which answers
    each step itself (`CoreLink`). A script that ends before the simulation leaves the wheels still from then on;
    one that raises or exits with a non-zero code ends the trial with a `ScriptError`."""

    needs_odom = False
    needs_proximity = False
    """What it reads comes from the simulation (joint states and raw IR values), not from the loop's Observation."""

    def __init__(self, stage: ScriptStage, robot: int, script: Path, arguments: tuple[str, ...] = ()) -> None:
        self.stage, self.robot, self.script, self.arguments = stage, robot, script, arguments
        names = stage.sim.names
        self.name = names[robot] if len(names) > 1 else SINGLE_ROBOT_NAME
        """The robot's name as `getName()` gives it over ROS."""
        self.exit_code: int | None = None
        """The script's exit code once it has ended (0: it returned, sys.exit(0), or step() returned -1)."""
        self.failure = ''
        """What went wrong, in one line, when the script failed."""
        self._thread: threading.Thread | None = None
        self._ending = threading.Lock()
        """Makes the script's end and its last answer one event for `update`."""

    def update(self, observation: Observation) -> WheelCommand | None:
        """None while the script runs (it answers from its thread; the first call starts it); then wheels still."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f'script {self.name}', daemon=True)
            self._thread.start()
            return None
        with self._ending:
            if self.exit_code is None:
                return None
        self.check()
        return WheelCommand(0.0, 0.0)

    def _run(self) -> None:
        bind_thread(CoreLink(self.stage, self.robot), self.name)
        code = 1
        try:
            code, self.failure = run_script(self.script, list(self.arguments))
        finally:
            with self._ending:
                self.exit_code = code
                self.stage.script_ended(self.robot)

    def join(self, timeout: float) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    def check(self) -> None:
        """Raise ScriptError if the script has ended with an error."""
        if self.exit_code:
            raise ScriptError(f'{self.script.name}: {self.failure or f"exit code {self.exit_code}"}', self.exit_code)
