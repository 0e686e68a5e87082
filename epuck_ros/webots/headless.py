"""Webots-style scripts on the pure core, in this process, with no ROS: the same `Robot` and devices as over ROS,
bound to a `CoreLink` instead of to the simulator's topics.

A script steps the world itself (`robot.step()` returns when the next step has happened), while a headless trial
is stepped by one loop that asks every robot's controller for its answer to each step
(`epuck_ros.experiments.trial.run`, the order of lockstep). A `ScriptSeat` joins the two: it is the robot's
controller in that loop, and the script runs in a thread of its own that the seat hands each step to, and takes
the script's answer from, as the simulator and the script's node exchange `joint_states`/`ir_raw` and `wheel_cmd`
in lockstep. The run is therefore the lockstep run over ROS, step for step.
"""
from __future__ import annotations

import queue
import threading
from pathlib import Path

from epuck_ros.behaviours import Observation, WheelCommand
from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_seconds
from epuck_ros.simulation import Simulation
from epuck_ros.webots.link import StepData
from epuck_ros.webots.robot import KILL_DELAY, SINGLE_ROBOT_NAME, bind_thread
from epuck_ros.webots.runner import run_script

_END = None
"""Handed to the script instead of a step: the simulation is over (its `step()` returns -1)."""


class ScriptError(RuntimeError):
    """The script ended with an error (raised, or exited with a non-zero code); the message says which."""


class CoreLink:
    """The Robot's link in a headless run: steps come from, and answers go to, the robot's `ScriptSeat`."""

    def __init__(self, seat: ScriptSeat) -> None:
        self._seat = seat

    def connect(self) -> float:
        return self._seat.time_step

    def first_step(self) -> StepData | None:
        return self._seat.to_script.get()

    def answer_and_wait(self, left: float, right: float) -> StepData | None:
        self._seat.from_script.put((left, right))
        return self._seat.to_script.get()

    def want(self, kind: str) -> None:
        """A device of sense `kind` was enabled: the core reads that sense for this robot from now on."""
        self._seat.want(kind)

    def publish_leds(self, values: list[int]) -> None:
        """No view to tell in a headless run."""

    def close(self) -> None:
        """Nothing to release: no node, no sockets."""


class ScriptSeat:
    """Robot `robot`'s controller in the headless loop, answered by a Webots-style script in a thread of its own.

    `update` hands the script the step just taken and returns the wheel speeds it answers with. A script that
    ends before the simulation leaves the wheels still from then on (as the simulator's cmd_timeout does over
    ROS); one that raises or exits with a non-zero code ends the trial with a `ScriptError`.
    """

    needs_odom = False
    needs_proximity = False
    """What it reads comes from `bind` (joint states and raw IR values), not from the loop's Observation."""

    def __init__(self, script: Path, time_step: float, arguments: tuple[str, ...] = ()) -> None:
        self.script, self.time_step, self.arguments = script, time_step, arguments
        self.name = SINGLE_ROBOT_NAME
        self.to_script: queue.SimpleQueue[StepData | None] = queue.SimpleQueue()
        self.from_script: queue.SimpleQueue[tuple[float, float] | int] = queue.SimpleQueue()
        self.exit_code: int | None = None
        """The script's exit code once it has ended (0: it returned, sys.exit(0), or step() returned -1)."""
        self.failure = ''
        """What went wrong, in one line, when the script failed."""
        self._sim: Simulation | None = None
        self._robot = 0
        self._thread: threading.Thread | None = None

    def bind(self, sim: Simulation, robot: int) -> None:
        """The simulation whose robot `robot` this seat answers for (its name as `getName()` gives it over ROS)."""
        self._sim, self._robot = sim, robot
        if len(sim.names) > 1:
            self.name = sim.names[robot]

    def want(self, kind: str) -> None:
        """Called from the script's thread inside its step(), while the loop waits for the answer."""
        self._sim.senses.want(kind, [self._robot])

    def update(self, observation: Observation) -> WheelCommand:
        sim, robot = self._sim, self._robot
        step = StepData(nanoseconds_from_stamp(*stamp_from_seconds(sim.time)), tuple(sim.wheel_angles[robot].tolist()),
                        tuple(sim.wheel_speeds[robot].tolist()), tuple(sim.ir_raw[robot].tolist()),
                        sim.senses.readings_of(robot))
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name=f'script {self.name}', daemon=True)
            self._thread.start()
        elif self.exit_code is not None:
            return WheelCommand(0.0, 0.0)
        self.to_script.put(step)
        answer = self.from_script.get()
        if isinstance(answer, int):   # the script has ended instead of answering
            self.check()
            return WheelCommand(0.0, 0.0)
        return WheelCommand(*answer)

    def _run(self) -> None:
        bind_thread(CoreLink(self), self.name)
        code = 1
        try:
            code, self.failure = run_script(self.script, list(self.arguments))
        finally:
            self.exit_code = code
            self.from_script.put(code)

    def close(self) -> None:
        """The end of the simulation: the script's step() returns -1; it has KILL_DELAY s to end (as in Webots),
        then it is left behind (a daemon thread)."""
        if self._thread is not None and self.exit_code is None:
            self.to_script.put(_END)
            self._thread.join(KILL_DELAY)

    def check(self) -> None:
        """Raise ScriptError if the script has ended with an error."""
        if self.exit_code:
            raise ScriptError(f'{self.script.name}: {self.failure or f"exit code {self.exit_code}"}')
