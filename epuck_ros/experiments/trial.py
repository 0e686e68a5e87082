"""One headless trial: a controller against the pure core, in this process, with no DDS.

A trial is (controller, world, robots, seed, duration, noise) and `run_trial` is a pure function of it: the same
trial gives the same rows on any machine, any worker, any retry. Its ground truth is that of the same run over
ROS, `bringup CONTROLLER --lockstep --real-time-factor 0 --seed S --duration D [--robots N] [--world W]`, to the
last bit, because it steps the core in the order lockstep does (nodes/sim_node.py, nodes/behaviour_nodes.py):
- the simulator takes its first step with no command (the wheels still), publishes it, and pauses itself on the
  first step at or after the duration (`pause_at`);
- each step is answered by every robot's controller, and the answers drive the next step: the controller of a
  robot sees what the simulator published, the IR values through `ranges_from_raw` and the odometry through its
  quaternion (`yaw_from_quaternion`), at the step's time; a Webots-style script's seat (`webots.headless`) reads
  the joint states and raw IR values the simulator published, as `webots_controller` does.
"""
from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from epuck_ros import untrusted_yaml
from epuck_ros.bag.tally import RunTally
from epuck_ros.behaviours import BEHAVIOURS, Behaviour, Observation, WheelCommand
from epuck_ros.behaviours.base import ConfigError, describe, ranges_from_raw
from epuck_ros.conversions import nanoseconds_from_seconds, quaternion_from_yaw, yaw_from_quaternion
from epuck_ros.experiments.isolation import ChildFailed, call_in_child
from epuck_ros.lockstep import Lockstep
from epuck_ros.model import TIME_STEP, RobotModel
from epuck_ros.simulation import Simulation
from epuck_ros.world import World, default_world, load_world, place_robots

if TYPE_CHECKING:
    from epuck_ros.experiments.recording import TrialRecorder
    from epuck_ros.webots.headless import ScriptSeat, ScriptStage

DEFAULT_WORLD = 'default'
"""A spec's name for the built-in world (`sim` with no `world` parameter)."""
DEFAULT_TIME_LIMIT = 600.0
"""Wall seconds a trial with a script may take by default (a spec's `time_limit`)."""
DEFAULT_MEMORY_LIMIT = 2048.0
"""Megabytes a trial with a script may take by default (a spec's `memory_limit`)."""
Policy = Callable[[Observation], WheelCommand]
"""A plain Python controller: an observation in, wheel speeds (rad/s) out."""
COLUMNS = ('trial', 'controller', 'world', 'robots', 'seed', 'robot', 'distance_m', 'contacts_obstacles',
           'contacts_robots', 'final_x', 'final_y', 'final_yaw', 'sim_time', 'wall_s', 'error', 'trial_key')
"""The columns of a trial's rows (`trials.csv`); `trial_key` is `Trial.key`."""
SETTING_TYPES = {float: 'a number', int: 'a whole number', bool: 'true or false', str: 'text'}
"""A behaviour setting's type is its default's (behaviours.base.setting): what a spec or a caller must give."""


@dataclass(frozen=True)
class Controller:
    """A built-in behaviour (`epuck_ros.behaviours.BEHAVIOURS`) with settings, as its ROS node takes them."""

    behaviour: str
    parameters: tuple[tuple[str, Any], ...] = ()

    @property
    def label(self) -> str:
        settings = ' '.join(f'{name}={value}' for name, value in self.parameters)
        return f'{self.behaviour}{" " + settings if settings else ""}'

    def make(self) -> Behaviour:
        spec = BEHAVIOURS[self.behaviour]
        return spec.make(replace(spec.defaults, **dict(self.parameters)))


@dataclass(frozen=True)
class Script:
    """A Webots-style controller script (`from controller import Robot`), as `bringup --controller SCRIPT` runs it:
    each robot runs it in a thread of its own (`epuck_ros.webots.headless`), and a trial with scripts runs in a
    process of its own (`isolation`), so that whatever a script does ends with its trial."""

    path: str
    name: str = ''
    """How the sweep names it (the `controller` column); '' = the file's name."""
    digest: str = ''
    """The SHA-256 of its source when the spec read it (part of its trials' keys)."""

    @property
    def label(self) -> str:
        return self.name or Path(self.path).name

    def stage(self, sim: Simulation, over: Callable[[], bool], recorder: TrialRecorder | None = None) -> ScriptStage:
        """The script's seats on `sim`, one per robot; `over()`: the run has taken its last step."""
        from epuck_ros.webots.headless import ScriptStage   # the shim's Robot imports rclpy (no DDS is started)
        return ScriptStage(Path(self.path), sim, over, recorder=recorder)


@dataclass(frozen=True)
class Trial:
    """Everything a run depends on; `world` is a path or DEFAULT_WORLD, `robots` 0 = the world's own."""

    controller: Controller | Script
    world: str = DEFAULT_WORLD
    robots: int = 0
    seed: int = 0
    duration: float = 60.0
    noise: bool = True
    index: int = 0
    """The trial's number in its sweep (its `trial` column); no effect on the run."""
    world_label: str = field(default=DEFAULT_WORLD, compare=False)
    """How the spec named the world (its `world` column)."""
    time_limit: float = DEFAULT_TIME_LIMIT
    """Wall seconds a trial with a script may take before its process is killed (the trial then fails)."""
    memory_limit: float = DEFAULT_MEMORY_LIMIT
    """Megabytes of resident memory a trial with a script may take beyond what its process started with (its
    processes together), before it is killed (the trial then fails)."""
    key: str = field(default='', compare=False)
    """What identifies its rows across runs of a sweep (the spec's hash of what they depend on), or ''."""
    record: str = ''
    """A folder to write the trial to as a rosbag2 MCAP bag (`recording`); '' = none. A retry writes it anew."""

    def load_world(self) -> World:
        world = default_world() if self.world == DEFAULT_WORLD else load_world(Path(self.world))
        return place_robots(world, self.robots, self.seed) if self.robots > 0 else world


def run_trial(trial: Trial, policy: Policy | None = None) -> list[dict[str, Any]]:
    """The trial's rows, one per robot (columns COLUMNS). A failure is a row with its `error`, never an exception:
    a sweep goes on. `policy` replaces the behaviour (a plain Python controller, the same for every robot).
    A trial with a script runs in a child process (`isolation`) under its time limit."""
    began = time.perf_counter()
    try:
        if isinstance(trial.controller, Script) and policy is None:
            import numpy.random  # noqa: F401 - loaded by numpy on first use (the noise): here once, not in every child
            import epuck_ros.webots.headless  # noqa: F401 - imported here once, not in every child
            return call_in_child(_rows, trial, trial.time_limit, trial.memory_limit * 1e6)
        return _rows(trial, policy)
    except Exception as error:  # noqa: BLE001 - whatever went wrong is the trial's result
        what = str(error) if isinstance(error, ChildFailed) else f'{type(error).__name__}: {error}'
        return failed_rows(trial, what, time.perf_counter() - began)


def failed_rows(trial: Trial, error: str, wall: float = math.nan) -> list[dict[str, Any]]:
    """A failed trial's rows: one per robot, as its rows would have been (names, robot count), each saying `error`;
    one row with no robot's name if even its world cannot be made."""
    try:
        names = trial.load_world().names
    except Exception:  # noqa: BLE001 - the error said is the trial's, not this one
        names = ('',)
    return [_row(trial, name, error=error, wall=wall, robots=len(names) if name else trial.robots)
            for name in names]


def _rows(trial: Trial, policy: Policy | None = None) -> list[dict[str, Any]]:
    began = time.perf_counter()
    if trial.record:
        from epuck_ros.experiments.recording import TrialRecorder
        shutil.rmtree(trial.record, ignore_errors=True)   # what a run cut short (a killed worker) left
        world = trial.load_world()
        recorder = TrialRecorder(Path(trial.record), world,
                                 controller_robots=1 if isinstance(trial.controller, Script) else len(world.robots))
        try:
            sim, tally = run(trial, policy, recorder=recorder)
        finally:
            recorder.close()
    else:
        sim, tally = run(trial, policy)
    wall = time.perf_counter() - began
    return [_row(trial, name, figures, sim.true_pose[i].tolist(), sim.time, wall, robots=len(sim.names))
            for i, (name, figures) in enumerate(zip(sim.names, tally.figures))]


def run(trial: Trial, policy: Policy | None = None, each_step: Callable[[Simulation], None] | None = None,
        recorder: TrialRecorder | None = None) -> tuple[Simulation, RunTally]:
    """Step the trial to its end: the simulation as it ended and the tally of its ground truth (what `bag
    summary` and `bringup` count); `each_step(sim)` sees every step as the simulator publishes it, `recorder` every
    step and what the controllers send."""
    world = trial.load_world()
    sim = Simulation(world, RobotModel(), time_step=TIME_STEP, seed=trial.seed, noise=trial.noise)
    several = len(world.robots) > 1
    labels = [name if several else '' for name in sim.names]
    """Each robot's name in the tally (one robot: '', as `bag summary` names a run's only robot)."""
    tally = RunTally(labels, world)
    duration = trial.duration

    def over() -> bool:   # the simulator pauses on the first step at or after the duration
        return sim.time + 1e-9 >= duration

    def publish(resend: bool) -> None:
        sim.step()
        if recorder is not None:
            recorder.step(sim)
        _published(sim, tally, each_step)

    stage = trial.controller.stage(sim, over, recorder) if isinstance(trial.controller, Script) and policy is None \
        else None
    controllers = stage.seats if stage is not None else [policy or trial.controller.make() for _ in sim.names]
    # What each controller's node subscribes (a plain policy gets everything), and how each is asked: looked up
    # once, not at every step (this loop runs once per robot per step, beside a core that is itself fast).
    robots = [(robot, _answerer(controller), getattr(controller, 'needs_odom', True),
               getattr(controller, 'needs_proximity', True)) for robot, controller in enumerate(controllers)]
    # Stepped as the sim node steps, through a Lockstep that waits for every robot (each has its controller). The
    # scripts answer from their own threads, and the thread of a step's last answer takes the next step itself.
    lockstep = stage.lockstep_for(publish) if stage is not None else Lockstep(len(sim.names), publish, over_dds=False)
    lockstep.claim()
    answered = recorder.answered if recorder is not None and stage is None else None   # a script's: its own thread
    try:
        _step_to_end(sim, lockstep, robots, over, stage, answered)
    finally:   # a script's step() returns -1
        if stage is not None:
            stage.close()
    if answered is not None:   # a behaviour's node commands a stop as it ends
        recorder.stop()
    if stage is not None:   # a script may fail after the end, too
        stage.check()
    return sim, tally


def _step_to_end(sim: Simulation, lockstep: Lockstep, robots: list[tuple[int, Callable, bool, bool]],
                 over: Callable[[], bool], stage: Any, answered: Callable[[int, float, float], None] | None) -> None:
    """The first step with the wheels still, then each step's answers and the next step until `over()`: every robot
    answers each step (a script from its own thread, which may take the next steps itself: the lent claim);
    `answered` is told each answer given here."""
    lockstep.step()
    while not over():
        now = _stamp_seconds(sim.time)
        for robot, update, needs_odom, needs_ranges in robots:
            odom = _odometry_as_received(sim.odom_pose[robot]) if needs_odom else None
            ranges = ranges_from_raw(sim.ir_raw[robot].tolist()) if needs_ranges else None
            command = update(Observation(now, odom, ranges))
            if command is not None:   # None: a script that answers from its thread
                sim.command_wheels(robot, command.left, command.right)
                if answered is not None:
                    answered(robot, command.left, command.right)
                lockstep.answer(robot)
        if not lockstep.await_answers():   # every robot answered (the scripts' threads may have stepped on)
            raise RuntimeError('lockstep: a robot did not answer its step')
        if stage is not None:
            stage.check()   # a script that failed ends the trial before the next step
            if over():   # the scripts' threads took the steps to the end (lent), and answered the last
                break
        lockstep.step()


def _answerer(controller: Behaviour | Policy | ScriptSeat) -> Callable[[Observation], WheelCommand | None]:
    """How a controller is asked for its command: a behaviour's or a seat's `update`, or the policy itself."""
    return controller.update if hasattr(controller, 'update') else controller


def _published(sim: Simulation, tally: RunTally, each_step: Callable[[Simulation], None] | None) -> None:
    """A step as the simulator publishes it: its ground truth (stamped with the step) into the tally, every robot's
    at once (the tally names them in the simulation's order)."""
    if each_step is not None:
        each_step(sim)
    stamp = nanoseconds_from_seconds(sim.time)   # the integer of the step's stamp, without the (sec, nanosec) pair
    tally.add_step(stamp, *sim.true_pose.T)


def _stamp_seconds(seconds: float) -> float:
    """A time as a controller receives it: a (sec, nanosec) stamp, back in seconds."""
    return nanoseconds_from_seconds(seconds) * 1e-9


def _odometry_as_received(pose: Sequence[float]) -> tuple[float, float, float]:
    """The odometry pose a node reads: the yaw travels as a quaternion about z (ros/robot_ports.py)."""
    x, y, yaw = (float(value) for value in pose)
    return x, y, yaw_from_quaternion(0.0, 0.0, *quaternion_from_yaw(yaw))


def _row(trial: Trial, robot: str, figures: Any = None, pose: Sequence[float] = (math.nan,) * 3,
         sim_time: float = math.nan, wall: float = math.nan, error: str = '', robots: int | None = None
         ) -> dict[str, Any]:
    return {
        'trial': trial.index, 'controller': trial.controller.label, 'world': trial.world_label,
        'robots': trial.robots if robots is None else robots, 'seed': trial.seed, 'robot': robot,
        'distance_m': figures.distance if figures else math.nan,
        'contacts_obstacles': figures.world_contacts if figures else '',
        'contacts_robots': figures.robot_contacts if figures else '',
        'final_x': pose[0], 'final_y': pose[1], 'final_yaw': pose[2], 'sim_time': sim_time, 'wall_s': wall,
        'error': error, 'trial_key': trial.key}


def controller_from(name: str, parameters: Mapping[str, Any] | None = None) -> Controller:
    """A Controller for behaviour `name` with `parameters`: each of the type of its default (a whole number for a
    number too) and checked as its Config checks them; ConfigError naming the setting otherwise."""
    if name not in BEHAVIOURS:
        raise ConfigError(f'no behaviour {name!r} (known: {", ".join(BEHAVIOURS)})')
    defaults = {setting: value for setting, value, *_ in describe(BEHAVIOURS[name].defaults)}
    for setting, value in (parameters or {}).items():
        if setting not in defaults:
            raise ConfigError(f'{setting}: {name} has no such setting (known: {", ".join(defaults)})')
        expected = type(defaults[setting])
        accepted = (int, float) if expected is float else expected   # a whole number is a number too
        if isinstance(value, bool) is not (expected is bool) or not isinstance(value, accepted):
            raise ConfigError(f'{setting}: expected {SETTING_TYPES[expected]}, got '
                              f'{untrusted_yaml.cut(repr(value), 60)}')
    controller = Controller(name, tuple(sorted((parameters or {}).items())))
    controller.make()
    return controller
