"""The simulator without ROS: e-puck state in arrays, wheel commands with a timeout, one `step()` at a time.

Each step, in order: the command (or zero after the timeout) is applied to the wheels; the true pose moves
along the exact arc and is pushed out of anything it ran into; the wheels turn whether or not the body could
move, so the encoders (and the odometry integrated from them) drift from the true pose when the robot is
blocked; then the IR sensors are cast from the new true pose.

State is kept as arrays with one row per robot, (N, ...), one robot per `world.robots` entry. Robots collide
with each other as with walls and see each other's bodies with their IR sensors.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from epuck_ros import ir_sensor
from epuck_ros.kinematics import clamp_wheels, integrate_arc, quantise, twist_from_wheels, wheels_from_twist
from epuck_ros.model import RobotModel
from epuck_ros.spatial import close_pairs
from epuck_ros.world import CONTACT_TOLERANCE, World

_SEPARATION_PASSES = 8
"""Passes of pushing overlapping robots apart per substep before the stuck ones go back (see _separate_robots)."""
_OVERLAP_TOLERANCE = 1e-9
"""m; robots closer than a diameter by less than this are touching, not overlapping (rounding of the push)."""


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
    noise (the only random draw); `noise=False` gives the exact table values. The arrays the properties return
    are the simulator's own state, updated in place by `step()`: read them, copy what you keep, do not write to
    them.
    """

    def __init__(self, world: World, model: RobotModel = RobotModel(), time_step: float = 0.032,
                 seed: int = 0, noise: bool = True, cmd_timeout: float = 0.5) -> None:
        if not (math.isfinite(time_step) and time_step > 0.0):
            raise ValueError(f'time_step must be a positive number of seconds, got {time_step}')
        self.world, self.model, self.time_step = world, model, float(time_step)
        self.noise = noise
        self.cmd_timeout = cmd_timeout
        """Seconds without a command before a robot's wheels stop; 0 = never. May be changed between steps."""
        self._rng = np.random.default_rng(seed)
        self._start = np.array([robot.pose for robot in world.robots], dtype=float)
        # Never move more than half the body radius between collision checks, so nothing tunnels through
        # a thin obstacle or another robot even with a long time step (one substep at 32 ms: 4 mm per step).
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
        self._wheel_speeds, self._command = np.empty((n, 2)), np.empty((n, 2))
        self._ir_raw, self._ir_range = np.empty((n, sensors)), np.empty((n, sensors))
        self._no_hits = np.full(n * sensors, np.inf)
        self._touching_obstacle, self._touching_robot = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        self._in_contact = np.zeros(n, dtype=bool)
        self._collisions, self._robot_collisions = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
        self._last_command_time = np.zeros(n)
        self._commanded = np.zeros(n, dtype=bool)
        self.reset()

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
        with np.errstate(over='ignore'):
            left, right = wheels_from_twist(float(v), float(w), self.model)
        self._set_command(robot, left, right)

    def _set_command(self, robot: int, left: float, right: float) -> None:
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < len(self._command):
            raise CommandError(f'command rejected: no robot {robot!r} (robots 0..{len(self._command) - 1})')
        self._command[robot] = clamp_wheels(float(left), float(right), self.model.max_wheel_speed)
        self._last_command_time[robot] = self.time
        self._commanded[robot] = True

    # --- stepping -----------------------------------------------------------------------------------------

    def step(self) -> StepEvents:
        """Advance the world by one `time_step`."""
        events = StepEvents()
        self._expire_commands(events)
        self._wheel_speeds[:] = self._command
        start = self._true.copy()
        obstacle = np.zeros(len(start), dtype=bool)
        robot = np.zeros(len(start), dtype=bool)
        v, w = twist_from_wheels(self._command[:, 0], self._command[:, 1], self.model)
        substep = self.time_step / self._substeps
        for _ in range(self._substeps):
            clear = self._true[:, :2].copy()
            for index, (x, y, yaw) in enumerate(self._true.tolist()):
                x, y, yaw = integrate_arc(x, y, yaw, float(v[index]), float(w[index]), substep)
                x, y, hit = self.world.push_disc_out(x, y, self.model.body_radius, tuple(clear[index]))
                self._true[index] = (x, y, yaw)
                obstacle[index] |= hit
            if len(start) > 1:
                robot |= self._separate_robots(clear)
        self._true_twist[:, 0], self._true_twist[:, 1] = v, w
        moved = obstacle | robot
        if moved.any():
            heading = start[:, 2] + 0.5 * w * self.time_step
            along = ((self._true[:, 0] - start[:, 0]) * np.cos(heading)
                     + (self._true[:, 1] - start[:, 1]) * np.sin(heading)) / self.time_step
            self._true_twist[moved, 0] = along[moved]
        self._count_contacts(obstacle, robot, events)
        for index, (left, right) in enumerate(self._command.tolist()):
            self._update_odometry(index, left, right)
        self._steps += 1
        self._sense()
        return events

    def _expire_commands(self, events: StepEvents) -> None:
        """Zero the command of every robot whose last command is older than `cmd_timeout` (if that is > 0)."""
        if self.cmd_timeout <= 0.0 or not self._commanded.any():
            return
        expired = self._commanded & (self.time - self._last_command_time > self.cmd_timeout)
        if expired.any():
            events.timed_out = np.flatnonzero(expired).tolist()
            self._command[expired] = 0.0
            self._commanded[expired] = False

    def _separate_robots(self, clear: np.ndarray) -> np.ndarray:
        """Push overlapping robots apart; a robot that cannot be freed goes back to `clear`. Which robots touch.

        Each overlapping pair moves apart by half the overlap each along the line between the centres, then out
        of walls and obstacles again, a few passes. Whatever still overlaps after that (a robot squeezed
        between another and a wall) returns to its clear position of the last substep, and so on until nothing
        overlaps: every robot's clear position was clear, so this ends, with no overlap and nobody tunnelled.
        """
        xy = self._true[:, :2]
        diameter = 2.0 * self.model.body_radius
        for _ in range(_SEPARATION_PASSES):
            first, second = close_pairs(xy, diameter - _OVERLAP_TOLERANCE)
            if not len(first):
                break
            delta = xy[first] - xy[second]
            distance = np.hypot(delta[:, 0], delta[:, 1])
            delta[distance == 0.0] = (1.0, 0.0)   # one robot on top of another: part them along x
            distance[distance == 0.0] = 1.0
            push = delta * (0.5 * (diameter - distance) / distance)[:, None]
            shift = np.zeros_like(xy)
            np.add.at(shift, first, push)
            np.add.at(shift, second, -push)
            xy += shift
            for index in np.unique(np.concatenate([first, second])).tolist():
                x, y, _ = self.world.push_disc_out(*xy[index], self.model.body_radius, tuple(clear[index]))
                xy[index] = (x, y)
        reverted = np.zeros(len(xy), dtype=bool)
        while True:
            first, second = close_pairs(xy, diameter - _OVERLAP_TOLERANCE)
            stuck = np.zeros(len(xy), dtype=bool)
            stuck[first] = stuck[second] = True
            stuck &= ~reverted
            if not stuck.any():
                break
            xy[stuck] = clear[stuck]
            reverted |= stuck
        first, second = close_pairs(xy, diameter + CONTACT_TOLERANCE)
        touching = np.zeros(len(xy), dtype=bool)
        touching[first] = touching[second] = True
        return touching

    def _count_contacts(self, obstacle: np.ndarray, robot: np.ndarray, events: StepEvents) -> None:
        """A contact is counted once, when it begins: with a wall or obstacle, and with another robot apart."""
        new_obstacle = obstacle & ~self._touching_obstacle
        new_robot = robot & ~self._touching_robot
        self._collisions += new_obstacle.astype(int) + new_robot.astype(int)
        self._robot_collisions += new_robot
        events.new_contacts = np.flatnonzero(new_obstacle | new_robot).tolist()
        self._touching_obstacle[:], self._touching_robot[:] = obstacle, robot
        self._in_contact[:] = obstacle | robot

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
        """Cast one ray per IR sensor from its pose on the true body: walls, obstacles and the other robots."""
        n = len(self._true)
        near_robots = close_pairs(self._true[:, :2], self._sensing_reach + self.model.body_radius) if n > 1 else ((), ())
        if len(near_robots[0]) or any(self.world.anything_within(x, y, self._sensing_reach)
                                      for x, y, _ in self._true.tolist()):
            yaw = self._true[:, 2:3]
            cos, sin = np.cos(yaw)[:, :, None], np.sin(yaw)[:, :, None]
            origins = self._true[:, None, :2] + cos * self._sensor_offsets + sin * self._sensor_offsets_left
            yaws = yaw + self._sensor_poses[:, 2]
            distance = self.world.cast_rays(origins.reshape(-1, 2), yaws.ravel(), self.model.ir_range)
            if len(near_robots[0]):
                distance = distance.reshape(n, -1)
                owner = np.concatenate(near_robots)
                target = np.concatenate(near_robots[::-1])
                hits = _ray_circle(origins[owner], yaws[owner], self._true[target, None, :2], self.model.body_radius)
                np.minimum.at(distance, owner, hits)
                distance = distance.ravel()
                distance[distance > self.model.ir_range] = np.inf
        else:
            distance = self._no_hits
        table = self.model.ir_table
        raw = ir_sensor.noisy_raw(distance, table, self._rng if self.noise else None)
        self._ir_raw[:] = raw.reshape(self._ir_raw.shape)
        self._ir_range[:] = ir_sensor.range_from_raw(raw, distance < np.inf, table).reshape(self._ir_range.shape)

    def reset(self) -> None:
        """Every robot back to its start pose with odometry, wheel angles and command zeroed; time and collision
        counts go on."""
        self._true[:] = self._start
        for state in (self._odom, self._true_twist, self._odom_twist, self._wheel_rotation, self._encoders,
                      self._wheel_speeds, self._command):
            state.fill(0.0)
        for flags in (self._in_contact, self._touching_obstacle, self._touching_robot, self._commanded):
            flags.fill(False)
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
    def robot_collisions(self) -> np.ndarray:
        """(N,) the contacts with another robot among `collisions`."""
        return self._robot_collisions

    @property
    def in_contact(self) -> np.ndarray:
        """(N,) whether the body touches a wall, an obstacle or another robot now."""
        return self._in_contact


def _ray_circle(origins: np.ndarray, yaws: np.ndarray, centres: np.ndarray, radius: float) -> np.ndarray:
    """Distance along each ray (origins (..., 2), yaws (...)) to a circle (centres broadcastable); inf if it misses.

    Only the near crossing counts, and only ahead of the origin: a ray starting inside the circle sees nothing.
    """
    dir_x, dir_y = np.cos(yaws), np.sin(yaws)
    from_x, from_y = origins[..., 0] - centres[..., 0], origins[..., 1] - centres[..., 1]
    half_b = from_x * dir_x + from_y * dir_y
    discriminant = half_b * half_b - (from_x * from_x + from_y * from_y - radius * radius)
    root = -half_b - np.sqrt(np.maximum(discriminant, 0.0))
    root[(discriminant < 0.0) | (root < 0.0)] = np.inf
    return root


def _require_finite(**values: ArrayLike) -> None:
    try:
        bad = {name: value for name, value in values.items() if not np.isfinite(np.asarray(value, float)).all()}
    except (TypeError, ValueError):
        raise CommandError(f'command rejected: speeds must be numbers, got {values}') from None
    if bad:
        described = ', '.join(f'{name}={value}' for name, value in bad.items())
        raise CommandError(f'command rejected: speeds must be finite numbers, got {described}')
