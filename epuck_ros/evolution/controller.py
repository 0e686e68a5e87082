"""OUT/evolved_controller.py: a Webots controller script holding the best genome, needing only `controller`.

It runs the network of `network.py` on the raw IR values the way the environment sees them (`envs.worlds`), in
plain Python, so it runs unchanged through `bringup --controller`, `webots_controller` or Webots itself.
"""
from __future__ import annotations

from collections.abc import Sequence

from epuck_ros.model import RobotModel

TEMPLATE = '''"""Obstacle avoidance evolved by `evolve` (Floreano and Mondada's network and fitness):
generation {generation}, fitness {fitness!r} (seed {seed}).

A single-layer network: eight IR activations and a bias to two motor neurons, each also fed both motor outputs of
the previous step; tanh outputs are the wheel speeds as fractions of the maximum.
Run: bringup --controller evolved_controller.py   or   webots_controller evolved_controller.py
"""
import math

from controller import Robot

GENOME = {genome!r}
FAR, NEAR = {far!r}, {near!r}  # raw IR value with nothing within range, and touching: activation 0 and 1
INPUTS = 8

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
motors = [robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor')]
for motor in motors:
    motor.setPosition(float('inf'))
    motor.setVelocity(0.0)
top_speed = motors[0].getMaxVelocity()
sensors = [robot.getDevice(f'ps{{index}}') for index in range(INPUTS)]
for sensor in sensors:
    sensor.enable(step_ms)


def activation(raw):
    return min(max((raw - FAR) / (NEAR - FAR), 0.0), 1.0)


def network(inputs, previous):
    """The two motor outputs for eight activations and the previous outputs."""
    values = list(inputs) + [1.0] + list(previous)
    width = len(values)
    return [math.tanh(sum(w * x for w, x in zip(GENOME[k * width:(k + 1) * width], values))) for k in range(2)]


speeds = [0.0, 0.0]
while robot.step(step_ms) != -1:
    speeds = network([activation(sensor.getValue()) for sensor in sensors], speeds)
    for motor, speed in zip(motors, speeds):
        motor.setVelocity(speed * top_speed)
'''


def controller_script(genome: Sequence[float], generation: int, fitness: float, seed: int,
                      model: RobotModel = RobotModel()) -> str:
    return TEMPLATE.format(genome=[float(w) for w in genome], generation=generation, fitness=float(fitness),
                           seed=seed, far=float(model.ir_table[-1, 1]), near=float(model.ir_table[0, 1]))
