"""The swarm path: every robot of a world stepped together in NumPy, with cell lists for who can meet whom.

The pair of `one_robot.OneRobotStepper`, with the same rule on arrays: robots collide with the walls and
obstacles as the one robot does, and with each other; they see each other's bodies with their sensors.
Which robots can touch or see each other is kept in `_pairs`, searched again only when someone has moved far.
"""
from __future__ import annotations

import numpy as np

from epuck_ros.kinematics import integrate_arc, quantise, twist_from_wheels
from epuck_ros.model import RobotModel
from epuck_ros.spatial import close_pairs
from epuck_ros.stepping.ir_ring import IrRing
from epuck_ros.stepping.state import RobotArrays, step_travel, substeps
from epuck_ros.world import CONTACT_TOLERANCE, World, collisions

_SEPARATION_PASSES = 8
"""Passes of pushing overlapping robots apart per substep before the stuck ones go back (see _separate)."""
_PAIR_SLACK = 0.01
"""m a robot may move beyond a step's travel before the robot pairs are searched again (see _cover_pairs)."""
_OVERLAP_TOLERANCE = 1e-9
"""m; robots closer than a diameter by less than this are touching, not overlapping (rounding of the push)."""


class SwarmStepper:
    """Moves all robots of a world together, out of obstacles and apart, turns their wheels and reads sensors."""

    def __init__(self, world: World, model: RobotModel, time_step: float, ir: IrRing, start: np.ndarray,
                 isolated: bool = False) -> None:
        self.world, self.model, self.time_step, self.ir = world, model, time_step, ir
        self.isolated = isolated
        """Each robot alone in its own copy of the world: no pairs, no robot contacts, no robot in a ray."""
        self._geometry = world.geometry
        self._substeps = substeps(model, time_step)
        count = len(start)
        self._first_arc_steps = np.repeat([time_step / self._substeps, 1.0], count)   # see _move
        self._touching_none = np.zeros(count, dtype=bool)
        self._touching_none.setflags(write=False)
        # Robot pairs that can touch or see each other (see _cover_pairs): found within the sensing reach plus a
        # body, plus room for each of the two robots to move `_slack` (a step's travel and a little more).
        self._slack = step_travel(model, time_step) + _PAIR_SLACK
        self._pair_reach = ir.reach + model.body_radius + 2.0 * self._slack
        self._pairs = (np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64))
        self._pairs_origin = start[:, :2].copy()

    def step(self, state: RobotArrays) -> tuple[np.ndarray, np.ndarray]:
        """Move (with the odometry) and sense; (touching an obstacle, touching another robot) (N,) each."""
        obstacle, robot, offsets = self._move(state)
        self._sense(state, offsets)
        return obstacle, robot

    def reset(self, state: RobotArrays) -> None:
        """Search the pairs afresh where the robots are now and sense there."""
        if not self.isolated:
            self._cover_pairs(state.true[:, :2], refresh=True)
        self._sense(state, None)

    def _sense(self, state: RobotArrays, offsets: np.ndarray | None) -> None:
        """Read the sensors; `offsets`: the pairs' centre offsets where the robots are, if the step has them."""
        first, second = self._pairs   # they cover the robots where they are: _separate or reset saw to it
        self.ir.sense_many(state.true, first, second, offsets)

    def _move(self, state: RobotArrays) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """All robots along their arcs, out of obstacles and apart, per substep; (touching obstacle, robot) (N,)
        and the pairs' offsets where the robots stopped if the last separation has them (None: compute them).

        The odometry's arcs (a whole step, from the encoders) go into the first substep's integrate_arc call as
        N more rows: the same arithmetic per row in half the NumPy calls.
        """
        radius, count = self.model.body_radius, len(state.true)
        v, w = state.command_twist[:, 0], state.command_twist[:, 1]
        distance, turn = self._encoder_travel(state)
        start = state.true.copy()
        obstacle = np.zeros(count, dtype=bool)
        robot = np.zeros(count, dtype=bool)
        xy, yaw = start[:, :2], start[:, 2]
        substep = self.time_step / self._substeps
        odom = state.odom
        offsets = None
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
            xy, hit = collisions.resolve_collision(self._geometry, arc_end, radius, clear)
            obstacle |= hit
            if not self.isolated:
                touching, offsets = self._separate(xy, clear, obstacle)
                robot |= touching
        state.true[:, :2], state.true[:, 2] = xy, yaw
        self._true_twist(state, start, obstacle | robot)
        return obstacle, robot, offsets

    def _true_twist(self, state: RobotArrays, start: np.ndarray, moved: np.ndarray) -> None:
        """The commanded twist, but for robots that touched something the forward speed they really covered."""
        v, w = state.command_twist[:, 0], state.command_twist[:, 1]
        x, y = state.true[:, 0], state.true[:, 1]
        state.true_twist[:, 0], state.true_twist[:, 1] = v, w
        if moved.any():
            heading = start[moved, 2] + 0.5 * w[moved] * self.time_step
            state.true_twist[moved, 0] = ((x[moved] - start[moved, 0]) * np.cos(heading)
                                          + (y[moved] - start[moved, 1]) * np.sin(heading)) / self.time_step

    def _cover_pairs(self, xy: np.ndarray, refresh: bool = False) -> None:
        """Make `_pairs` hold every pair of robots that can touch or see each other at positions `xy`.

        The pairs are found within `_pair_reach`, which leaves each robot `_slack` of room; they are searched
        again only once some robot has moved farther than that from where it was at the last search: every few
        steps at a swarm's usual speeds. close_pairs gives them in one canonical order and every use filters
        them by distance, so the results are the same to the bit as with a fresh search every step.
        """
        if not refresh:
            moved = xy - self._pairs_origin
            moved *= moved
            refresh = float((moved[:, 0] + moved[:, 1]).max()) > self._slack ** 2
        if refresh:
            self._pairs = close_pairs(xy, self._pair_reach)
            self._pairs_origin = xy.copy()

    def _separate(self, xy: np.ndarray, clear: np.ndarray,
                  obstacle: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Push overlapping robots (xy, in place) apart; one that cannot be freed goes back to `clear`. Which
        touch, and the pairs' centre offsets where the robots stay when nobody touches (else None).

        Each pass parts the overlapping pairs (`_part`) and pushes them out of walls and obstacles again
        (`obstacle` records those contacts). Whatever still overlaps after the passes returns to its clear
        position of this substep (`_revert_stuck`): every clear position was clear, so this ends with no
        overlap and nobody tunnelled.
        """
        diameter = 2.0 * self.model.body_radius
        blocked = np.zeros(len(xy), dtype=bool)
        for _ in range(_SEPARATION_PASSES):
            self._cover_pairs(xy)
            first, second = self._pairs
            delta = xy[first] - xy[second]
            distance = np.hypot(delta[:, 0], delta[:, 1])
            if not len(distance) or distance.min() >= diameter + CONTACT_TOLERANCE:
                return self._touching_none, delta   # nobody overlaps or touches: the common case
            over = (distance < diameter - _OVERLAP_TOLERANCE).nonzero()[0]
            if not len(over):
                break
            self._part(xy, clear, obstacle, blocked, first[over], second[over], delta[over], distance[over])
        else:
            first, second, distance = self._revert_stuck(xy, clear)
        touching = np.zeros(len(xy), dtype=bool)
        close = distance < diameter + CONTACT_TOLERANCE
        touching[first[close]] = touching[second[close]] = True
        return touching, None

    def _part(self, xy: np.ndarray, clear: np.ndarray, obstacle: np.ndarray, blocked: np.ndarray,
              pushed: np.ndarray, pusher: np.ndarray, delta: np.ndarray, distance: np.ndarray) -> None:
        """One pass: part each overlapping pair (pushed, pusher; centre offset `delta`, `distance`) along the line
        between the centres, in place in `xy`, then out of walls and obstacles.

        The overlap is shared by how far each robot came into the contact this substep: a robot driving into an
        idle one shoves it along (at its own speed), two robots driving at each other share it. A shove reaches
        one robot further per pass, so a row of a few robots is pushed along as a whole, and packs up against a
        wall. `blocked` marks the robots a wall or obstacle holds.
        """
        diameter = 2.0 * self.model.body_radius
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
        xy[moved], hit = collisions.resolve_collision(self._geometry, wanted, self.model.body_radius, clear[moved])
        obstacle[moved] |= hit
        blocked[moved] |= (xy[moved] != wanted).any(axis=1)   # a wall or obstacle stopped it

    def _revert_stuck(self, xy: np.ndarray, clear: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Send every robot that still overlaps back to `clear`, until none does; the pairs and their distances."""
        diameter = 2.0 * self.model.body_radius
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
                return first, second, distance
            xy[stuck] = clear[stuck]
            reverted |= stuck

    def _encoder_travel(self, state: RobotArrays) -> tuple[np.ndarray, np.ndarray]:
        """Turn every robot's wheels by its command and read the encoders: (distance, turn) (N,) of this step as
        the odometry sees them (the one-robot stepper's formulas on columns); sets the odometry's twist."""
        rotation, dt = state.wheel_rotation, self.time_step
        rotation += state.command * dt
        encoders = quantise(rotation, self.model.encoder_resolution)
        change = encoders - state.encoders
        state.encoders[:] = encoders
        distance, turn = twist_from_wheels(change[:, 0], change[:, 1], self.model)
        state.odom_twist[:, 0], state.odom_twist[:, 1] = distance / dt, turn / dt
        return distance, turn
