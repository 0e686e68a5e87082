"""One robot's fast path: the same step as the swarm stepper's, on plain Python floats.

For one robot NumPy's per-call overhead costs more than its few dozen operations, so this stepper works on
floats; `swarm.SwarmStepper` is its pair for several robots. Both follow one rule (tests run the same scene
through each), and both leave the sensing to the sensor parts.
"""
from __future__ import annotations

import math

from epuck_ros.kinematics import integrate_arc, quantise, twist_from_wheels
from epuck_ros.model import RobotModel
from epuck_ros.stepping.ir_ring import IrRing
from epuck_ros.stepping.state import RobotArrays, substeps
from epuck_ros.world import World, collisions


class OneRobotStepper:
    """Moves the only robot of a world along its exact arc, turns its wheels and reads its sensors."""

    def __init__(self, world: World, model: RobotModel, time_step: float, ir: IrRing) -> None:
        self.world, self.model, self.time_step, self.ir = world, model, time_step, ir
        self._geometry = world.geometry
        self._substeps = substeps(model, time_step)

    def step(self, state: RobotArrays) -> tuple[bool, bool]:
        """Move, update the odometry, sense; (touching an obstacle, touching a robot) as plain bools."""
        obstacle = self._move(state)
        self._update_odometry(state)
        self.sense(state)
        return obstacle, False

    def reset(self, state: RobotArrays) -> None:
        """Sense where the robot now is (the one robot keeps nothing else between steps)."""
        self.sense(state)

    def sense(self, state: RobotArrays) -> None:
        """Read the sensors from the true pose."""
        (x, y, yaw), = state.true.tolist()
        self.ir.sense_one(x, y, yaw)

    def _move(self, state: RobotArrays) -> bool:
        """The robot along its exact arc, pushed out of obstacles after each substep; whether it touched.

        The true twist is the commanded one unless the body touched something; then its forward speed is what
        the body really covered along its heading (zero when blocked head-on).
        """
        (v, w), = state.command_twist.tolist()
        (start_x, start_y, start_yaw), = state.true.tolist()
        x, y, yaw = start_x, start_y, start_yaw
        touching = False
        substep = self.time_step / self._substeps
        for _ in range(self._substeps):
            clear = (x, y)
            x, y, yaw = integrate_arc(x, y, yaw, v, w, substep)
            x, y, hit = collisions.push_disc_out(self._geometry, x, y, self.model.body_radius, clear)
            touching = touching or hit
        state.true[0] = (x, y, yaw)
        forward = v
        if touching:
            heading = start_yaw + 0.5 * w * self.time_step
            forward = ((x - start_x) * math.cos(heading) + (y - start_y) * math.sin(heading)) / self.time_step
        state.true_twist[0] = (forward, w)
        return touching

    def _update_odometry(self, state: RobotArrays) -> None:
        """Wheels turn at the applied speed even when the body is blocked; odometry sees only the encoders."""
        resolution, dt = self.model.encoder_resolution, self.time_step
        (rotation_left, rotation_right), = state.wheel_rotation.tolist()   # rows as tuples: one assignment each
        (left, right), = state.command.tolist()
        (last_left, last_right), = state.encoders.tolist()
        rotation_left, rotation_right = rotation_left + left * dt, rotation_right + right * dt
        encoder_left, encoder_right = quantise(rotation_left, resolution), quantise(rotation_right, resolution)
        distance, turn = twist_from_wheels(encoder_left - last_left, encoder_right - last_right, self.model)
        state.wheel_rotation[0] = (rotation_left, rotation_right)
        state.encoders[0] = (encoder_left, encoder_right)
        state.odom[0] = integrate_arc(*state.odom[0].tolist(), distance, turn, 1.0)
        state.odom_twist[0] = (distance / dt, turn / dt)
