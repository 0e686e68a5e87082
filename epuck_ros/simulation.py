"""The simulator without ROS: e-puck state in arrays, wheel commands with a timeout, one `step()` at a time.

Each step, in order: the command (or zero after the timeout) is applied to the wheels; the true pose moves
along the exact arc and is pushed out of anything it ran into; the wheels turn whether or not the body could
move, so the encoders (and the odometry integrated from them) drift from the true pose when the robot is
blocked; then the sensors are read from the new true pose.

State is kept as arrays with one row per robot, (N, ...), one robot per `world.robots` entry
(`stepping.state.RobotArrays`). Robots collide with each other as with walls and see each other's bodies with
their IR sensors. The motion is one of two paired steppers: `stepping.one_robot` on plain floats for a single
robot, `stepping.swarm` in NumPy for several; the sensors are parts they compose (`stepping.ir_ring`); the other
senses (`stepping.senses`) are read after the step for the robots that want them. This
module keeps what both share: the commands and their timeout, the contact count, time and the public API.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from epuck_ros.kinematics import clamp_wheels, twist_from_wheels, wheels_from_twist
from epuck_ros.model import TIME_STEP, RobotModel
from epuck_ros.stepping.ir_ring import IrRing
from epuck_ros.stepping.senses import Senses
from epuck_ros.stepping.one_robot import OneRobotStepper
from epuck_ros.stepping.state import RobotArrays
from epuck_ros.stepping.swarm import SwarmStepper
from epuck_ros.world import World


MAX_SEED = 2**31 - 1
"""The largest seed of a run, wherever it is given (the sim's `seed` parameter, a sweep's spec, `--headless`): one
bound, so that every seed a headless trial takes, `bringup --seed` takes too and repeats the run."""


class CommandError(ValueError):
    """A command the simulator refuses (NaN or infinite speeds); the robot keeps its previous command."""


@dataclass
class StepEvents:
    """What happened during one step that a node may want to log once, not every step."""

    new_contacts: list[int] = field(default_factory=list)
    """Robots whose body started touching a wall, an obstacle or another robot in this step."""
    timed_out: list[int] = field(default_factory=list)
    """Robots that stopped in this step because no command arrived for `cmd_timeout` seconds."""


class Simulation:
    """The robots of a World, stepped by `time_step`; read the public properties after each `step()`.

    Robot i is `world.robots[i]` (`names[i]`); every state array has one row per robot. `seed` seeds the IR
    noise (and, each from its own stream, the other senses' noise); `noise=False` gives the exact table values.
    `isolated=True` puts each robot alone in its own copy of the world: robots neither touch nor see each other
    (independent worlds stepped together, as a vector environment needs). The arrays the properties return are
    the simulator's own state, updated in place by `step()`: read them, copy what you keep, do not write to them.
    """

    def __init__(self, world: World, model: RobotModel = RobotModel(), time_step: float = TIME_STEP,
                 seed: int = 0, noise: bool = True, cmd_timeout: float = 0.5, isolated: bool = False) -> None:
        if not (math.isfinite(time_step) and time_step > 0.0):
            raise ValueError(f'time_step must be a positive number of seconds, got {time_step}')
        self.world, self.model, self.time_step = world, model, float(time_step)
        self.cmd_timeout = cmd_timeout
        """Seconds without a command before a robot's wheels stop; 0 = never. May be changed between steps."""
        self._start = np.array([robot.pose for robot in world.robots], dtype=float)
        n = len(self._start)
        self._state = RobotArrays.empty(n)
        self._ir = IrRing(world, model, n, np.random.default_rng(seed), noise)
        self._stepper: OneRobotStepper | SwarmStepper = (
            OneRobotStepper(world, model, self.time_step, self._ir) if n == 1
            else SwarmStepper(world, model, self.time_step, self._ir, self._start, isolated))
        self.senses = Senses(world, self._state, self.time_step, seed, noise, isolated=isolated)
        """Camera, ground, light sensors, IMU and ToF: read after each step for the robots that want them (`want`)."""
        self._steps = 0
        self._last_command_time = np.zeros(n)
        self._commanded = np.zeros(n, dtype=bool)
        self._earliest_command = math.inf
        """No commanded robot's last command is older than this: below the timeout, no array is looked at."""
        self.reset()

    @property
    def noise(self) -> bool:
        """Whether the IR readings are noisy (the exact table values when not); may be changed between steps."""
        return self._ir.noise

    @noise.setter
    def noise(self, noise: bool) -> None:
        self._ir.noise = self.senses.noise = noise

    @property
    def names(self) -> tuple[str, ...]:
        """The robots' names, in row order (a robot's ROS ports live under its name)."""
        return self.world.names

    # --- commands -----------------------------------------------------------------------------------------

    def command_wheels(self, robot: int, left: float, right: float) -> None:
        """Set one robot's wheel speeds (rad/s), each clamped to +-max_wheel_speed; NaN or inf raises CommandError."""
        _require_finite(left=left, right=right)
        self._set_command(robot, left, right)

    def command_twist(self, robot: int, v: float, w: float) -> None:
        """Drive one robot at `v` m/s and `w` rad/s: converted to wheel speeds, then clamped per wheel.

        Only v and w must be finite: a huge finite speed converts to an infinite wheel speed, which the clamp
        turns into full speed, as `command_wheels` does with a huge wheel speed.
        """
        _require_finite(v=v, w=w)
        left, right = wheels_from_twist(float(v), float(w), self.model)   # float overflow gives inf, no error
        self._set_command(robot, left, right)

    def command_all_wheels(self, speeds: np.ndarray) -> None:
        """Set every robot's wheel speeds (rad/s) at once, `speeds` (N, 2): `command_wheels` row by row, in one NumPy
        operation (a vector environment commands thousands of robots a step). Nothing is set if a row is refused."""
        state = self._state
        try:
            speeds = np.asarray(speeds, dtype=float)
        except (TypeError, ValueError):
            raise CommandError('command rejected: speeds must be numbers') from None
        if speeds.shape != state.command.shape:
            raise CommandError(f'command rejected: wheel speeds of shape {state.command.shape} expected, '
                               f'got {speeds.shape}')
        finite = np.isfinite(speeds).all(axis=1)
        if not finite.all():
            rows = np.flatnonzero(~finite)
            raise CommandError(f'command rejected: speeds must be finite numbers, not in rows {rows[:10].tolist()}')
        top = self.model.max_wheel_speed
        state.command[:] = np.clip(speeds, -top, top)
        state.command_twist[:, 0], state.command_twist[:, 1] = twist_from_wheels(
            state.command[:, 0], state.command[:, 1], self.model)
        self._last_command_time[:] = self.time
        self._commanded[:] = True
        self._earliest_command = min(self._earliest_command, self.time)

    def _set_command(self, robot: int, left: float, right: float) -> None:
        state = self._state
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < len(state.command):
            raise CommandError(f'command rejected: no robot {robot!r} (robots 0..{len(state.command) - 1})')
        left, right = clamp_wheels(float(left), float(right), self.model.max_wheel_speed)
        state.command[robot] = left, right
        state.command_twist[robot] = twist_from_wheels(left, right, self.model)
        self._last_command_time[robot] = self.time
        self._commanded[robot] = True
        self._earliest_command = min(self._earliest_command, self.time)

    # --- stepping -----------------------------------------------------------------------------------------

    def step(self) -> StepEvents:
        """Advance the world by one `time_step`: one robot on the float stepper, several on the swarm stepper."""
        events = StepEvents()
        self._expire_commands(events)
        self._state.wheel_speeds[:] = self._state.command
        obstacle, robot = self._stepper.step(self._state)
        self._count_contacts(obstacle, robot, events)
        if self.senses.active:
            self.senses.step = self._steps + 1
            self.senses.sense(self._state)
        self._steps += 1
        return events

    def _expire_commands(self, events: StepEvents) -> None:
        """Zero the command of every robot whose last command is older than `cmd_timeout` (if that is > 0)."""
        if self.cmd_timeout <= 0.0 or self.time - self._earliest_command <= self.cmd_timeout:
            return
        expired = self._commanded & (self.time - self._last_command_time > self.cmd_timeout)
        if expired.any():
            events.timed_out = np.flatnonzero(expired).tolist()
            self._state.command[expired] = self._state.command_twist[expired] = 0.0
            self._commanded[expired] = False
        self._earliest_command = float(self._last_command_time[self._commanded].min(initial=math.inf))

    def _count_contacts(self, obstacle: bool | np.ndarray, robot: bool | np.ndarray, events: StepEvents) -> None:
        """A contact is counted once, when it begins: with a wall or obstacle, and with another robot apart."""
        state = self._state
        if isinstance(obstacle, bool):   # the one robot (robot is False): plain bools, no array work
            if obstacle and not state.touching_obstacle[0]:
                state.collisions[0] += 1
                events.new_contacts = [0]
            if obstacle or state.in_contact[0]:
                state.touching_obstacle[0] = state.in_contact[0] = obstacle
            return
        if not (obstacle.any() or robot.any() or state.in_contact.any()):
            return   # no robot touches anything, nor did: the common case in a swarm
        new_obstacle = obstacle & ~state.touching_obstacle
        new_robot = robot & ~state.touching_robot
        state.collisions += new_obstacle.astype(int) + new_robot.astype(int)
        state.robot_collisions += new_robot
        events.new_contacts = np.flatnonzero(new_obstacle | new_robot).tolist()
        state.touching_obstacle[:], state.touching_robot[:] = obstacle, robot
        state.in_contact[:] = obstacle | robot

    def reset(self) -> None:
        """Every robot back to its start pose with odometry, wheel angles and command zeroed; time and collision
        counts go on."""
        self._state.reset(self._start)
        self._commanded.fill(False)
        self._earliest_command = math.inf
        self._stepper.reset(self._state)
        self.senses.reset()

    # --- state --------------------------------------------------------------------------------------------

    @property
    def time(self) -> float:
        """Simulated seconds since construction (counted in whole steps, so it never drifts)."""
        return self._steps * self.time_step

    @property
    def steps(self) -> int:
        return self._steps

    @property
    def true_pose(self) -> np.ndarray:
        """(N, 3) x, y (m), yaw (rad) in the world frame."""
        return self._state.true

    @property
    def true_twist(self) -> np.ndarray:
        """(N, 2) forward speed (m/s) and yaw rate (rad/s) the body really had; zero when blocked."""
        return self._state.true_twist

    @property
    def odom_pose(self) -> np.ndarray:
        """(N, 3) pose integrated from the encoders, starting at (0, 0, 0) where the robot started."""
        return self._state.odom

    @property
    def odom_twist(self) -> np.ndarray:
        """(N, 2) forward speed and yaw rate from the encoder changes over the last step."""
        return self._state.odom_twist

    @property
    def wheel_angles(self) -> np.ndarray:
        """(N, 2) left, right wheel angles (rad) as the encoders read them (quantised)."""
        return self._state.encoders

    @property
    def wheel_speeds(self) -> np.ndarray:
        """(N, 2) left, right wheel speeds (rad/s) applied in the last step (after clamp and timeout)."""
        return self._state.wheel_speeds

    @property
    def ir_raw(self) -> np.ndarray:
        """(N, 8) raw IR values of ps0..ps7, noisy unless noise is off."""
        return self._ir.raw

    @property
    def ir_range(self) -> np.ndarray:
        """(N, 8) IR ranges (m) of ps0..ps7 in [0, 0.07]; inf where nothing is within 0.07 m."""
        return self._ir.range

    @property
    def collisions(self) -> np.ndarray:
        """(N,) number of contacts so far, each counted once when it began."""
        return self._state.collisions

    @property
    def robot_collisions(self) -> np.ndarray:
        """(N,) the contacts with another robot among `collisions`."""
        return self._state.robot_collisions

    @property
    def in_contact(self) -> np.ndarray:
        """(N,) whether the body touches a wall, an obstacle or another robot now."""
        return self._state.in_contact


def _require_finite(**values: float) -> None:
    """Raise CommandError unless every value is a finite float (math.isfinite: NumPy would cost more per command)."""
    try:
        bad = {name: value for name, value in values.items() if not _is_finite_float(value)}
    except TypeError:
        raise CommandError(f'command rejected: speeds must be numbers, got {values}') from None
    if bad:
        described = ', '.join(f'{name}={value}' for name, value in bad.items())
        raise CommandError(f'command rejected: speeds must be finite numbers, got {described}')


def _is_finite_float(value: float) -> bool:
    try:
        return math.isfinite(value)
    except OverflowError:   # an integer beyond any float
        return False
