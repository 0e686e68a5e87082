"""OUT/evolved_controller.py: a Webots controller script holding the best genome, needing only `controller`.

It runs the network of `network.py` on the raw IR values the way the environment sees them (`envs.worlds.activations`:
the distance each value stands for on the lookup table, as a share of the sensors' reach), in plain Python, so it
runs unchanged through `bringup --controller`, `webots_controller` or Webots itself.
"""
from __future__ import annotations

import textwrap
from collections.abc import Sequence

from epuck_ros.envs.worlds import reach
from epuck_ros.model import RobotModel

TEMPLATE = '''"""Obstacle avoidance evolved by `evolve` (Floreano and Mondada's network and fitness):
generation {generation}, fitness {fitness!r} (seed {seed}).

A single-layer network: eight IR activations and a bias to two motor neurons, each also fed both motor outputs of
the previous step; tanh outputs are the wheel speeds as fractions of the maximum.
Run: bringup --controller evolved_controller.py   or   webots_controller evolved_controller.py
"""
import bisect
import math

from controller import Robot

GENOME = {genome}
# the IR lookup table by increasing raw value: raw value -> distance (m)
RAWS = {raws}
DISTANCES = {distances}
REACH = {reach!r}  # m: the farthest a sensor tells something from nothing (its noise above the free value)
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
    """1 - d / REACH: d the distance (m) the raw value stands for on the table (linear between its rows and beyond
    its ends), at most REACH. 0: nothing seen; 1: touching."""
    k = bisect.bisect_right(RAWS, raw, 1, len(RAWS) - 1) - 1
    slope = (DISTANCES[k + 1] - DISTANCES[k]) / (RAWS[k + 1] - RAWS[k])
    distance = min(max(DISTANCES[k] + (raw - RAWS[k]) * slope, 0.0), DISTANCES[0])
    return 1.0 - min(distance, REACH) / REACH


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
    table = model.ir_table[::-1]
    return TEMPLATE.format(genome=listing(genome), generation=generation, fitness=float(fitness), seed=seed,
                           raws=listing(table[:, 1]), distances=listing(table[:, 0]), reach=reach(model))


def listing(values: Sequence[float]) -> str:
    """A list of floats as Python source, one per repr (they read back exactly), wrapped within the line length."""
    lines = textwrap.wrap(', '.join(repr(float(value)) for value in values), width=112, break_long_words=False,
                          break_on_hyphens=False)
    return '[\n' + ''.join(f'    {line}\n' for line in lines) + ']'
