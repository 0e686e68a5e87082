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

from epuck_ros import ir_sensor
from epuck_ros.kinematics import clamp_wheels, integrate_arc, quantise, twist_from_wheels, wheels_from_twist
from epuck_ros.model import RobotModel
from epuck_ros.spatial import close_pairs
from epuck_ros.world import CONTACT_TOLERANCE, World, ray_circle

_SEPARATION_PASSES = 8
"""Passes of pushing overlapping robots apart per substep before the stuck ones go back (see _separate_robots)."""
_SENSE_BLOCK = 512
"""Robots whose rays are cast together (see Simulation._sense)."""
_PAIR_SLACK = 0.01
"""m a robot may move beyond a step's travel before the robot pairs are searched again (see Simulation._cover_pairs)."""
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
    noise (the only random draw); `noise=False` gives the exact table values. `isolated=True` puts each robot alone
    in its own copy of the world: robots neither touch nor see each other (independent worlds stepped together, as a
    vector environment needs). The arrays the properties return are the simulator's own state, updated in place by
    `step()`: read them, copy what you keep, do not write to them.
    """

    def __init__(self, world: World, model: RobotModel = RobotModel(), time_step: float = 0.032,
                 seed: int = 0, noise: bool = True, cmd_timeout: float = 0.5, isolated: bool = False) -> None:
        if not (math.isfinite(time_step) and time_step > 0.0):
            raise ValueError(f'time_step must be a positive number of seconds, got {time_step}')
        self.world, self.model, self.time_step = world, model, float(time_step)
        self.noise, self.isolated = noise, isolated
        self.cmd_timeout = cmd_timeout
        """Seconds without a command before a robot's wheels stop; 0 = never. May be changed between steps."""
        self._rng = np.random.default_rng(seed)
        self._start = np.array([robot.pose for robot in world.robots], dtype=float)
        # Never move more than half the body radius between collision checks, so nothing tunnels through
        # a thin obstacle or another robot even with a long time step (one substep at 32 ms: 4 mm per step).
        fastest = model.max_wheel_speed * model.wheel_radius * self.time_step
        self._substeps = max(1, math.ceil(fastest / (0.5 * model.body_radius)))
        poses = np.asarray(model.sensor_poses, dtype=float)
        # Each sensor's position on the body, that position turned 90 deg, and its yaw: turned by the robot's yaw
        # each step. As rows (offset x, offset y, left x, left y, yaw) of floats for one robot, and as columns
        # (8, 1) for many robots, whose rays are (8, N) arrays.
        layout = np.column_stack([poses[:, 0], poses[:, 1], -poses[:, 1], poses[:, 0], poses[:, 2]])
        self._sensor_rows = layout.tolist()
        self._sensor_columns = tuple(column[:, None].copy() for column in layout.T)
        self._sensor_cos, self._sensor_sin = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])   # (8, 1)
        self._sensor_index = np.arange(len(poses))[:, None]
        self._ir_table = ir_sensor.LookupTable(model.ir_table)
        # Beyond this distance from the body's centre no IR ray can reach anything: the sensor farthest out plus
        # the ray. Farther from every surface, a step casts no rays at all.
        self._sensing_reach = float(np.hypot(poses[:, 0], poses[:, 1]).max()) + model.ir_range
        self._steps = 0
        n, sensors = len(self._start), len(poses)
        self._first_arc_steps = np.repeat([self.time_step / self._substeps, 1.0], n)   # see _move_many
        self._true, self._odom = np.empty((n, 3)), np.empty((n, 3))
        self._true_twist, self._odom_twist = np.empty((n, 2)), np.empty((n, 2))
        self._wheel_rotation, self._encoders = np.empty((n, 2)), np.empty((n, 2))
        self._wheel_speeds, self._command = np.empty((n, 2)), np.empty((n, 2))
        self._command_twist = np.empty((n, 2))
        """(v, w) of each robot's command, kept with it: many robots' steps then need no conversion."""
        self._ir_raw, self._ir_range = np.empty((n, sensors)), np.empty((n, sensors))
        self._touching_obstacle, self._touching_robot = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        self._touching_none = np.zeros(n, dtype=bool)
        self._touching_none.setflags(write=False)
        self._in_contact = np.zeros(n, dtype=bool)
        self._collisions, self._robot_collisions = np.zeros(n, dtype=int), np.zeros(n, dtype=int)
        self._last_command_time = np.zeros(n)
        self._commanded = np.zeros(n, dtype=bool)
        self._earliest_command = math.inf
        """No commanded robot's last command is older than this: below the timeout, no array is looked at."""
        # Robot pairs that can touch or see each other (see _cover_pairs): found within the sensing reach plus a
        # body, plus room for each of the two robots to move `_slack` (a step's travel and a little more).
        self._slack = fastest + _PAIR_SLACK
        self._pair_reach = self._sensing_reach + model.body_radius + 2.0 * self._slack
        self._pairs = (np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64))
        self._pairs_origin = self._start[:, :2].copy()
        self._pair_offsets: np.ndarray | None = None
        """The pairs' centre offsets (first minus second) where the robots are, when the step already has them."""
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
        left, right = wheels_from_twist(float(v), float(w), self.model)   # float overflow gives inf, no error
        self._set_command(robot, left, right)

    def _set_command(self, robot: int, left: float, right: float) -> None:
        if isinstance(robot, bool) or not isinstance(robot, (int, np.integer)) or not 0 <= robot < len(self._command):
            raise CommandError(f'command rejected: no robot {robot!r} (robots 0..{len(self._command) - 1})')
        left, right = clamp_wheels(float(left), float(right), self.model.max_wheel_speed)
        self._command[robot] = left, right
        self._command_twist[robot] = twist_from_wheels(left, right, self.model)
        self._last_command_time[robot] = self.time
        self._commanded[robot] = True
        self._earliest_command = min(self._earliest_command, self.time)

    # --- stepping -----------------------------------------------------------------------------------------

    def step(self) -> StepEvents:
        """Advance the world by one `time_step`.

        One robot moves on plain floats (NumPy's per-call overhead would cost more than its few dozen
        operations: about 2x slower, measured with benchmarks/bench_core.py); several robots move together in
        NumPy, with cell lists for which robots can touch or see each other.
        """
        events = StepEvents()
        self._expire_commands(events)
        self._wheel_speeds[:] = self._command
        if len(self._true) == 1:
            obstacle, robot = self._move_one(), False   # plain bools: _count_contacts' fast path
            self._update_odometry()
        else:
            obstacle, robot = self._move_many()   # the odometry too
        self._count_contacts(obstacle, robot, events)
        self._steps += 1
        self._sense()
        return events

    def _expire_commands(self, events: StepEvents) -> None:
        """Zero the command of every robot whose last command is older than `cmd_timeout` (if that is > 0)."""
        if self.cmd_timeout <= 0.0 or self.time - self._earliest_command <= self.cmd_timeout:
            return
        expired = self._commanded & (self.time - self._last_command_time > self.cmd_timeout)
        if expired.any():
            events.timed_out = np.flatnonzero(expired).tolist()
            self._command[expired] = self._command_twist[expired] = 0.0
            self._commanded[expired] = False
        self._earliest_command = float(self._last_command_time[self._commanded].min(initial=math.inf))

    def _move_one(self) -> bool:
        """The only robot along its exact arc, pushed out of obstacles after each substep; whether it touched.

        The true twist is the commanded one unless the body touched something; then its forward speed is what
        the body really covered along its heading (zero when blocked head-on).
        """
        (v, w), = self._command_twist.tolist()
        (start_x, start_y, start_yaw), = self._true.tolist()
        x, y, yaw = start_x, start_y, start_yaw
        touching = False
        substep = self.time_step / self._substeps
        for _ in range(self._substeps):
            clear = (x, y)
            x, y, yaw = integrate_arc(x, y, yaw, v, w, substep)
            x, y, hit = self.world.push_disc_out(x, y, self.model.body_radius, clear)
            touching = touching or hit
        self._true[0] = (x, y, yaw)
        forward = v
        if touching:
            heading = start_yaw + 0.5 * w * self.time_step
            forward = ((x - start_x) * math.cos(heading) + (y - start_y) * math.sin(heading)) / self.time_step
        self._true_twist[0] = (forward, w)
        return touching

    def _move_many(self) -> tuple[np.ndarray, np.ndarray]:
        """All robots along their arcs, out of obstacles and apart, per substep; (touching obstacle, robot) (N,).

        The odometry's arcs (a whole step, from the encoders) go into the first substep's integrate_arc call as
        N more rows: the same arithmetic per row in half the NumPy calls (for 50 robots 30 us instead of 42,
        measured).
        """
        radius, count = self.model.body_radius, len(self._true)
        v, w = self._command_twist[:, 0], self._command_twist[:, 1]
        distance, turn = self._encoder_travel()
        start = self._true.copy()
        obstacle = np.zeros(count, dtype=bool)
        robot = np.zeros(count, dtype=bool)
        xy, yaw = start[:, :2], start[:, 2]
        substep = self.time_step / self._substeps
        odom = self._odom
        for k in range(self._substeps):
            clear = xy
            if k == 0:
                x, y, yaw = integrate_arc(np.concatenate([xy[:, 0], odom[:, 0]]),
                                          np.concatenate([xy[:, 1], odom[:, 1]]), np.concatenate([yaw, odom[:, 2]]),
                                          np.concatenate([v, distance]), np.concatenate([w, turn]),
                                          self._first_arc_steps)
                odom[:, 0], odom[:, 1], odom[:, 2] = x[count:], y[count:], yaw[count:]
                x, y, yaw = x[:count], y[:count], yaw[:count]
            else:
                x, y, yaw = integrate_arc(xy[:, 0], xy[:, 1], yaw, v, w, substep)
            arc_end = np.empty((count, 2))
            arc_end[:, 0], arc_end[:, 1] = x, y
            xy, hit = self.world.resolve_collision(arc_end, radius, clear)
            obstacle |= hit
            if not self.isolated:
                robot |= self._separate_robots(xy, clear, obstacle)
        self._true[:, :2], self._true[:, 2] = xy, yaw
        x, y = xy[:, 0], xy[:, 1]
        self._true_twist[:, 0], self._true_twist[:, 1] = v, w
        moved = obstacle | robot
        if moved.any():
            heading = start[moved, 2] + 0.5 * w[moved] * self.time_step
            self._true_twist[moved, 0] = ((x[moved] - start[moved, 0]) * np.cos(heading)
                                          + (y[moved] - start[moved, 1]) * np.sin(heading)) / self.time_step
        return obstacle, robot

    def _cover_pairs(self, xy: np.ndarray, refresh: bool = False) -> None:
        """Make `_pairs` hold every pair of robots that can touch or see each other at positions `xy`.

        The pairs are found within `_pair_reach`, which leaves each robot `_slack` of room; they are searched
        again only once some robot has moved farther than that from where it was at the last search: every few
        steps at a swarm's usual speeds (a search is a sixth of a 1,000-robot step, measured). close_pairs gives
        them in one canonical order and every use filters them by distance, so the results are the same to the
        bit as with a fresh search every step.
        """
        if len(xy) == 1:
            return
        if not refresh:
            moved = xy - self._pairs_origin
            moved *= moved
            refresh = float((moved[:, 0] + moved[:, 1]).max()) > self._slack ** 2
        if refresh:
            self._pairs = close_pairs(xy, self._pair_reach)
            self._pairs_origin = xy.copy()

    def _separate_robots(self, xy: np.ndarray, clear: np.ndarray, obstacle: np.ndarray) -> np.ndarray:
        """Push overlapping robots (xy, in place) apart; one that cannot be freed goes back to `clear`. Which touch.

        Each overlapping pair is parted along the line between the centres, the overlap shared by how far each
        robot came into the contact this substep: a robot driving into an idle one shoves it along (at its own
        speed), two robots driving at each other share it. Then out of walls and obstacles again (`obstacle`
        records those contacts). A shove reaches one robot further per pass, so a row of a few robots is pushed
        along as a whole, and packs up against a wall. Whatever still overlaps after the passes returns to its
        clear position of this substep, and so on until nothing overlaps: every clear position was clear, so
        this ends with no overlap and nobody tunnelled.
        """
        diameter = 2.0 * self.model.body_radius
        blocked = np.zeros(len(xy), dtype=bool)
        self._pair_offsets = None
        for _ in range(_SEPARATION_PASSES):
            self._cover_pairs(xy)
            first, second = self._pairs
            delta = xy[first] - xy[second]
            distance = np.hypot(delta[:, 0], delta[:, 1])
            if not len(distance) or distance.min() >= diameter + CONTACT_TOLERANCE:
                self._pair_offsets = delta   # where the robots stay: _see_robots needs them too
                return self._touching_none   # nobody overlaps or touches: the common case
            over = (distance < diameter - _OVERLAP_TOLERANCE).nonzero()[0]
            if not len(over):
                break
            pushed, pusher, delta, distance = first[over], second[over], delta[over], distance[over]
            delta[distance == 0.0] = (1.0, 0.0)   # one robot right on top of another: part them along x
            distance[distance == 0.0] = 1.0
            normal = delta / distance[:, None]   # from `pusher` towards `pushed`
            came_in = np.maximum(-np.einsum('ij,ij->i', xy[pushed] - clear[pushed], normal), 0.0)
            other_came_in = np.maximum(np.einsum('ij,ij->i', xy[pusher] - clear[pusher], normal), 0.0)
            total = came_in + other_came_in
            share = np.divide(other_came_in, total, out=np.full(len(total), 0.5), where=total > 0.0)
            # A robot held by a wall (or by a robot so held) does not give way: the other takes the whole
            # overlap and is held in turn, so a row pressed against a wall packs up against it.
            share[blocked[pushed] & ~blocked[pusher]] = 0.0
            share[blocked[pusher] & ~blocked[pushed]] = 1.0
            blocked[pusher[share == 0.0]] |= blocked[pushed[share == 0.0]]
            blocked[pushed[share == 1.0]] |= blocked[pusher[share == 1.0]]
            overlap = (diameter - distance)[:, None] * normal
            shift = np.zeros_like(xy)
            np.add.at(shift, pushed, overlap * share[:, None])
            np.add.at(shift, pusher, overlap * (share - 1.0)[:, None])
            moved = np.unique(np.concatenate([pushed, pusher]))
            wanted = xy[moved] + shift[moved]
            xy[moved], hit = self.world.resolve_collision(wanted, self.model.body_radius, clear[moved])
            obstacle[moved] |= hit
            blocked[moved] |= (xy[moved] != wanted).any(axis=1)   # a wall or obstacle stopped it
        else:
            reverted = np.zeros(len(xy), dtype=bool)
            while True:
                self._cover_pairs(xy)
                first, second = self._pairs
                delta = xy[first] - xy[second]
                distance = np.hypot(delta[:, 0], delta[:, 1])
                over = distance < diameter - _OVERLAP_TOLERANCE
                stuck = np.zeros(len(xy), dtype=bool)
                stuck[first[over]] = stuck[second[over]] = True
                stuck &= ~reverted
                if not stuck.any():
                    break
                xy[stuck] = clear[stuck]
                reverted |= stuck
        touching = np.zeros(len(xy), dtype=bool)
        close = distance < diameter + CONTACT_TOLERANCE
        touching[first[close]] = touching[second[close]] = True
        return touching

    def _count_contacts(self, obstacle: np.ndarray, robot: np.ndarray, events: StepEvents) -> None:
        """A contact is counted once, when it begins: with a wall or obstacle, and with another robot apart."""
        if isinstance(obstacle, bool):   # the one robot (robot is False): plain bools, no array work
            if obstacle and not self._touching_obstacle[0]:
                self._collisions[0] += 1
                events.new_contacts = [0]
            if obstacle or self._in_contact[0]:
                self._touching_obstacle[0] = self._in_contact[0] = obstacle
            return
        if isinstance(obstacle, np.ndarray) and not (obstacle.any() or robot.any() or self._in_contact.any()):
            return   # no robot touches anything, nor did: the common case in a swarm
        new_obstacle = obstacle & ~self._touching_obstacle
        new_robot = robot & ~self._touching_robot
        self._collisions += new_obstacle.astype(int) + new_robot.astype(int)
        self._robot_collisions += new_robot
        events.new_contacts = np.flatnonzero(new_obstacle | new_robot).tolist()
        self._touching_obstacle[:], self._touching_robot[:] = obstacle, robot
        self._in_contact[:] = obstacle | robot

    def _update_odometry(self) -> None:
        """Wheels turn at the applied speed even when the body is blocked; odometry sees only the encoders.

        One robot, on floats (many robots: _encoder_travel, and the arcs in _move_many).
        """
        resolution, dt = self.model.encoder_resolution, self.time_step
        (rotation_left, rotation_right), = self._wheel_rotation.tolist()   # rows as tuples: one assignment per array
        (left, right), = self._command.tolist()
        (last_left, last_right), = self._encoders.tolist()
        rotation_left, rotation_right = rotation_left + left * dt, rotation_right + right * dt
        encoder_left, encoder_right = quantise(rotation_left, resolution), quantise(rotation_right, resolution)
        distance, turn = twist_from_wheels(encoder_left - last_left, encoder_right - last_right, self.model)
        self._wheel_rotation[0] = (rotation_left, rotation_right)
        self._encoders[0] = (encoder_left, encoder_right)
        self._odom[0] = integrate_arc(*self._odom[0].tolist(), distance, turn, 1.0)
        self._odom_twist[0] = (distance / dt, turn / dt)

    def _encoder_travel(self) -> tuple[np.ndarray, np.ndarray]:
        """Turn every robot's wheels by its command and read the encoders: (distance, turn) (N,) of this step as
        the odometry sees them (_update_odometry's formulas on columns); sets the odometry's twist."""
        rotation, dt = self._wheel_rotation, self.time_step
        rotation += self._command * dt
        encoders = quantise(rotation, self.model.encoder_resolution)
        change = encoders - self._encoders
        self._encoders[:] = encoders
        distance, turn = twist_from_wheels(change[:, 0], change[:, 1], self.model)
        self._odom_twist[:, 0], self._odom_twist[:, 1] = distance / dt, turn / dt
        return distance, turn

    def _sense(self) -> None:
        """Cast one ray per IR sensor from its pose on the true body: walls, obstacles and the other robots.

        One robot: plain floats (_sense_one). Many: every ray is cast against walls and the obstacles near its
        robot (World.ray_distances) and against the bodies of the robots within reach (the step's pairs), each
        robot's own body excepted. Every part takes the robots (or the robots seeing each other) in blocks of
        _SENSE_BLOCK: NumPy's temporaries then stay in the CPU cache (4x faster than whole (10,000, 8, k) arrays,
        measured), and one block is all of them up to 512 robots.
        """
        count = len(self._true)
        if count == 1:
            self._sense_one()
            return
        cos, sin = np.cos(self._true[:, 2]), np.sin(self._true[:, 2])
        if count <= _SENSE_BLOCK:
            distance = np.ascontiguousarray(self._cast(slice(0, count), cos, sin))   # _see_robots writes a flat view
        else:
            distance = np.empty((len(self._sensor_rows), count))
            for start in range(0, count, _SENSE_BLOCK):
                rows = slice(start, min(start + _SENSE_BLOCK, count))
                distance[:, rows] = self._cast(rows, cos[rows], sin[rows])
        if not self.isolated:
            self._see_robots(distance, cos, sin)
        for start in range(0, count, _SENSE_BLOCK):   # the noise is drawn robot by robot, as one draw would be
            rows = slice(start, min(start + _SENSE_BLOCK, count))
            self._read_sensors(rows, distance[:, rows].T.ravel())

    def _sense_one(self) -> None:
        """The only robot's rays and readings on Python floats, with `_cast` and `_read_sensors`' arithmetic.

        Only the surfaces within the sensing reach are tested, none when nothing is that near. On arrays of 8,
        NumPy's per-call cost dominates: the same work took 50 us near a wall and 19 us far from everything,
        this takes 16 us and 6 us (measured in the default world).
        """
        (x, y, yaw), = self._true.tolist()
        surfaces = self.world.surfaces_near(x, y, self._sensing_reach)
        distances = None
        if surfaces:
            cos, sin = math.cos(yaw), math.sin(yaw)
            rays = [(x + cos * offset_x + sin * left_x, y + cos * offset_y + sin * left_y,
                     math.cos(yaw + turn), math.sin(yaw + turn))
                    for offset_x, offset_y, left_x, left_y, turn in self._sensor_rows]
            distances = self.world.cast_near(surfaces, rays, self.model.ir_range)
        sensors = len(self._sensor_rows)
        normals = self._rng.standard_normal(sensors).tolist() if self.noise else None
        self._ir_raw[0], self._ir_range[0] = self._ir_table.read_one(distances, normals, sensors)

    def _cast(self, rows: slice, cos: np.ndarray, sin: np.ndarray) -> np.ndarray:
        """Distance (8, n) along each IR ray of the robots `rows` (cos, sin of their yaws (n,)) to walls and
        obstacles; one row per sensor, so the robots are the long, contiguous axis (see World.ray_distances)."""
        x, y, yaw = self._true[rows, 0], self._true[rows, 1], self._true[rows, 2]
        offset_x, offset_y, left_x, left_y, turn = self._sensor_columns
        yaws = yaw + turn
        return self.world.ray_distances(x + cos * offset_x + sin * left_x, y + cos * offset_y + sin * left_y,
                                        np.cos(yaws), np.sin(yaws), self.model.ir_range, self._true[rows, :2],
                                        self._sensing_reach - self.model.ir_range)

    def _read_sensors(self, rows: slice, distance: np.ndarray) -> None:
        """Raw values (noisy unless noise is off) and published ranges of the robots `rows` from their ray
        distances (n * 8,), robot by robot."""
        table = self._ir_table
        raw = ir_sensor.noisy_raw(distance, table.table, self._rng if self.noise else None)
        self._ir_raw[rows] = raw.reshape(-1, self._ir_raw.shape[1])
        ranges = ir_sensor.range_from_raw(raw, distance < np.inf, table.table, table.inverse)
        self._ir_range[rows] = ranges.reshape(-1, self._ir_range.shape[1])

    def _see_robots(self, distance: np.ndarray, cos: np.ndarray, sin: np.ndarray) -> None:
        """Lower `distance` (8, N) where a ray meets another robot's body first; cos, sin (N,) of the yaws.

        Each close pair gives two viewers (each robot looks at the other), the other's centre turned into the
        viewer's frame, where the viewer's 8 rays are constants: one broadcast (8, viewers) with no per-ray
        gathers. np.minimum.at then keeps each ray's nearest hit, whatever the order of the pairs (no sort).
        """
        first, second = self._pairs   # they cover the robots where they are: _separate_robots or reset saw to it
        offsets = self._pair_offsets   # first's centre minus second's, if _separate_robots has them
        if offsets is None:
            offsets = self._true[first, :2] - self._true[second, :2]
        dx, dy = offsets[:, 0], offsets[:, 1]
        near = (dx * dx + dy * dy < (self._sensing_reach + self.model.body_radius) ** 2).nonzero()[0]
        if not len(near):
            return
        viewer = np.concatenate([second[near], first[near]])   # second sees first at +offset, first sees second at -
        dx, dy = dx[near], dy[near]
        dx, dy = np.concatenate([dx, -dx]), np.concatenate([dy, -dy])
        cos, sin = cos[viewer], sin[viewer]
        local_x, local_y = cos * dx + sin * dy, cos * dy - sin * dx
        offset_x, offset_y, *_ = self._sensor_columns
        flat = distance.reshape(-1)
        for start in range(0, len(viewer), _SENSE_BLOCK):
            part = slice(start, start + _SENSE_BLOCK)
            hits = ray_circle(offset_x, offset_y, self._sensor_cos, self._sensor_sin, local_x[part], local_y[part],
                              self.model.body_radius)
            hits[hits > self.model.ir_range] = np.inf
            np.minimum.at(flat, (viewer[part] + self._sensor_index * len(self._true)).ravel(), hits.ravel())

    def reset(self) -> None:
        """Every robot back to its start pose with odometry, wheel angles and command zeroed; time and collision
        counts go on."""
        self._true[:] = self._start
        if not self.isolated:
            self._cover_pairs(self._true[:, :2], refresh=True)
        self._pair_offsets = None
        for state in (self._odom, self._true_twist, self._odom_twist, self._wheel_rotation, self._encoders,
                      self._wheel_speeds, self._command, self._command_twist):
            state.fill(0.0)
        for flags in (self._in_contact, self._touching_obstacle, self._touching_robot, self._commanded):
            flags.fill(False)
        self._earliest_command = math.inf
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


def _require_finite(**values: float) -> None:
    """CommandError unless every value is a finite float (math.isfinite: a NumPy call costs ~8 us per command)."""
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
