"""The simulator without ROS: e-puck state in arrays, wheel commands with a timeout, one `step()` at a time.

Each step, in order: the command (or zero after the timeout) is applied to the wheels; the true pose moves
along the exact arc and is pushed out of anything it ran into; the wheels turn whether or not the body could
move, so the encoders (and the odometry integrated from them) drift from the true pose when the robot is
blocked; then the IR sensors are cast from the new true pose.

State is kept as arrays with one row per robot, (N, ...), so that several robots are a change of N rather than
a rewrite; today the constructor builds one robot, at the world's start pose.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from epuck_ros import ir_sensor
from epuck_ros.kinematics import clamp_wheels, integrate_arc, quantise, twist_from_wheels, wheels_from_twist
from epuck_ros.model import RobotModel
from epuck_ros.world import World


class CommandError(ValueError):
    """A command the simulator refuses (NaN or infinite speeds); the robot keeps its previous command."""


@dataclass
class StepEvents:
    """What happened during one step that a node may want to log once, not every step."""

    new_contacts: list[int] = field(default_factory=list)
    """Robots whose body started touching a wall or obstacle in this step."""
    timed_out: list[int] = field(default_factory=list)
    """Robots that stopped in this step because no command arrived for `cmd_timeout` seconds."""


class Simulation:
    """One e-puck in a World, stepped by `time_step`; read the public properties after each `step()`.

    `seed` seeds the IR noise (the only random draw); `noise=False` gives the exact table values. The arrays
    the properties return are the simulator's own state, updated in place by `step()`: read them, copy what
    you keep, do not write to them.
    """

    def __init__(self, world: World, model: RobotModel = RobotModel(), time_step: float = 0.032,
                 seed: int = 0, noise: bool = True, cmd_timeout: float = 0.5) -> None:
        if not (math.isfinite(time_step) and time_step > 0.0):
            raise ValueError(f'time_step must be a positive number of seconds, got {time_step}')
        self.world, self.model, self.time_step = world, model, float(time_step)
        self.noise = noise
        self.cmd_timeout = cmd_timeout
        """Seconds without a command before the wheels stop; 0 = never. May be changed between steps."""
        self._rng = np.random.default_rng(seed)
        self._start = np.array([world.start_pose], dtype=float)
        # Never move more than half the body radius between collision checks, so nothing tunnels through
        # a thin obstacle even with a long time step (one substep at the default 32 ms: 4 mm per step).
        fastest = model.max_wheel_speed * model.wheel_radius * self.time_step
        self._substeps = max(1, math.ceil(fastest / (0.5 * model.body_radius)))
        self._sensor_poses = np.asarray(model.sensor_poses, dtype=float)
        # Sensor positions on the body as x-axis and y-axis parts: origin = xy + cos(yaw) a + sin(yaw) b.
        self._sensor_offsets = self._sensor_poses[:, :2].copy()
        self._sensor_offsets_left = np.column_stack([-self._sensor_poses[:, 1], self._sensor_poses[:, 0]])
        # Beyond this distance from the body's centre no IR ray can reach anything: the sensor farthest out plus
        # the ray. Farther from every surface, a step casts no rays at all.
        self._sensing_reach = float(np.hypot(*self._sensor_poses[:, :2].T).max()) + model.ir_range
        self._steps = 0
        n, sensors = len(self._start), len(self._sensor_poses)
        self._true, self._odom = np.empty((n, 3)), np.empty((n, 3))
        self._true_twist, self._odom_twist = np.empty((n, 2)), np.empty((n, 2))
        self._wheel_rotation, self._encoders = np.empty((n, 2)), np.empty((n, 2))
        self._wheel_speeds, self._command, self._stopped = np.empty((n, 2)), np.empty((n, 2)), np.zeros((n, 2))
        self._ir_raw, self._ir_range = np.empty((n, sensors)), np.empty((n, sensors))
        self._no_hits = np.full(n * sensors, np.inf)
        self._in_contact = np.zeros(n, dtype=bool)
        self._collisions = np.zeros(n, dtype=int)
        self._last_command_time = 0.0
        self._timed_out = False
        self.reset()

    # --- commands -----------------------------------------------------------------------------------------

    def command_wheels(self, left: ArrayLike, right: ArrayLike) -> None:
        """Set the wheel speeds (rad/s), each clamped to +-max_wheel_speed; NaN or inf raises CommandError."""
        _require_finite(left=left, right=right)
        self._command[:, 0], self._command[:, 1] = clamp_wheels(left, right, self.model.max_wheel_speed)
        self._last_command_time = self.time

    def command_twist(self, v: ArrayLike, w: ArrayLike) -> None:
        """Drive at `v` m/s and `w` rad/s: converted to wheel speeds, then clamped per wheel like `command_wheels`."""
        _require_finite(v=v, w=w)
        self.command_wheels(*wheels_from_twist(v, w, self.model))

    # --- stepping -----------------------------------------------------------------------------------------

    def step(self) -> StepEvents:
        """Advance the world by one `time_step`.

        Each robot's motion is a few dozen float operations, done in plain Python (NumPy's per-call overhead
        would cost more at this size); the IR rays of all robots are cast in one NumPy batch.
        """
        events = StepEvents()
        speeds = self._applied_speeds(events)
        self._wheel_speeds[:] = speeds
        for robot, (left, right) in enumerate(speeds.tolist()):
            touching = self._move_body(robot, left, right)
            if touching and not self._in_contact[robot]:
                self._collisions[robot] += 1
                events.new_contacts.append(robot)
            self._in_contact[robot] = touching
            self._update_odometry(robot, left, right)
        self._steps += 1
        self._sense()
        return events

    def _applied_speeds(self, events: StepEvents) -> np.ndarray:
        """The commanded speeds, or zero once the last command is older than `cmd_timeout` (if that is > 0)."""
        if self.cmd_timeout <= 0.0 or self.time - self._last_command_time <= self.cmd_timeout:
            self._timed_out = False
            return self._command
        if not self._timed_out:
            events.timed_out = list(range(len(self._command)))
            self._timed_out = True
        return self._stopped

    def _move_body(self, robot: int, left: float, right: float) -> bool:
        """Exact arc for the true pose, the body pushed out of obstacles after each substep; whether it touched.

        The true twist is the commanded one unless the body touched something; then its forward speed is what
        the body really covered along its heading (zero when blocked head-on).
        """
        v, w = twist_from_wheels(left, right, self.model)
        start_x, start_y, start_yaw = x, y, yaw = self._true[robot].tolist()
        touching = False
        substep = self.time_step / self._substeps
        for _ in range(self._substeps):
            clear = (x, y)
            x, y, yaw = integrate_arc(x, y, yaw, v, w, substep)
            x, y, hit = self.world.push_disc_out(x, y, self.model.body_radius, clear)
            touching = touching or hit
        self._true[robot] = (x, y, yaw)
        forward = v
        if touching:
            heading = start_yaw + 0.5 * w * self.time_step
            forward = ((x - start_x) * math.cos(heading) + (y - start_y) * math.sin(heading)) / self.time_step
        self._true_twist[robot] = (forward, w)
        return touching

    def _update_odometry(self, robot: int, left: float, right: float) -> None:
        """Wheels turn at the applied speed even when the body is blocked; odometry sees only the encoders."""
        rotation_left, rotation_right = self._wheel_rotation[robot].tolist()
        rotation_left += left * self.time_step
        rotation_right += right * self.time_step
        self._wheel_rotation[robot] = (rotation_left, rotation_right)
        resolution = self.model.encoder_resolution
        encoder_left, encoder_right = quantise(rotation_left, resolution), quantise(rotation_right, resolution)
        last_left, last_right = self._encoders[robot].tolist()
        self._encoders[robot] = (encoder_left, encoder_right)
        distance, turn = twist_from_wheels(encoder_left - last_left, encoder_right - last_right, self.model)
        self._odom[robot] = integrate_arc(*self._odom[robot].tolist(), distance, turn, 1.0)
        self._odom_twist[robot] = (distance / self.time_step, turn / self.time_step)

    def _sense(self) -> None:
        """Cast one ray per IR sensor from its pose on the true body; raw values and published ranges."""
        if any(self.world.anything_within(x, y, self._sensing_reach) for x, y, _ in self._true.tolist()):
            yaw = self._true[:, 2:3]
            cos, sin = np.cos(yaw)[:, :, None], np.sin(yaw)[:, :, None]
            origins = self._true[:, None, :2] + cos * self._sensor_offsets + sin * self._sensor_offsets_left
            distance = self.world.cast_rays(origins.reshape(-1, 2), (yaw + self._sensor_poses[:, 2]).ravel(),
                                            self.model.ir_range)
        else:
            distance = self._no_hits
        table = self.model.ir_table
        raw = ir_sensor.noisy_raw(distance, table, self._rng if self.noise else None)
        self._ir_raw[:] = raw.reshape(self._ir_raw.shape)
        self._ir_range[:] = ir_sensor.range_from_raw(raw, distance < np.inf, table).reshape(self._ir_range.shape)

    def reset(self) -> None:
        """Back to the start pose with odometry, wheel angles and command zeroed; time and collision count go on."""
        self._true[:] = self._start
        for state in (self._odom, self._true_twist, self._odom_twist, self._wheel_rotation, self._encoders,
                      self._wheel_speeds, self._command):
            state.fill(0.0)
        self._in_contact.fill(False)
        self._sense()

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
        return self._true

    @property
    def true_twist(self) -> np.ndarray:
        """(N, 2) forward speed (m/s) and yaw rate (rad/s) the body really had; zero when blocked."""
        return self._true_twist

    @property
    def odom_pose(self) -> np.ndarray:
        """(N, 3) pose integrated from the encoders, starting at (0, 0, 0) where the robot started."""
        return self._odom

    @property
    def odom_twist(self) -> np.ndarray:
        """(N, 2) forward speed and yaw rate from the encoder changes over the last step."""
        return self._odom_twist

    @property
    def wheel_angles(self) -> np.ndarray:
        """(N, 2) left, right wheel angles (rad) as the encoders read them (quantised)."""
        return self._encoders

    @property
    def wheel_speeds(self) -> np.ndarray:
        """(N, 2) left, right wheel speeds (rad/s) applied in the last step (after clamp and timeout)."""
        return self._wheel_speeds

    @property
    def ir_raw(self) -> np.ndarray:
        """(N, 8) raw IR values of ps0..ps7, noisy unless noise is off."""
        return self._ir_raw

    @property
    def ir_range(self) -> np.ndarray:
        """(N, 8) IR ranges (m) of ps0..ps7 in [0, 0.07]; inf where nothing is within 0.07 m."""
        return self._ir_range

    @property
    def collisions(self) -> np.ndarray:
        """(N,) number of contacts so far, each counted once when it began."""
        return self._collisions

    @property
    def in_contact(self) -> np.ndarray:
        """(N,) whether the body touches a wall or obstacle now."""
        return self._in_contact


def _require_finite(**values: ArrayLike) -> None:
    try:
        bad = {name: value for name, value in values.items() if not np.isfinite(np.asarray(value, float)).all()}
    except (TypeError, ValueError):
        raise CommandError(f'command rejected: speeds must be numbers, got {values}') from None
    if bad:
        described = ', '.join(f'{name}={value}' for name, value in bad.items())
        raise CommandError(f'command rejected: speeds must be finite numbers, got {described}')
