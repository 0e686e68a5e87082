"""Obstacle avoidance evolved by `evolve` (Floreano and Mondada's network and fitness):
generation 93, fitness 0.7580438774110291 (seed 1).

A single-layer network: eight IR activations and a bias to two motor neurons, each also fed both motor outputs of
the previous step; tanh outputs are the wheel speeds as fractions of the maximum.
Run: bringup --controller evolved_controller.py   or   webots_controller evolved_controller.py
"""
import bisect
import math

from controller import Robot

GENOME = [
    -2.5982968965739133, -2.577731375043832, -2.173642860418988, 1.654266125855672, 0.4059697995238323,
    -0.4999134040979784, -0.5351012307442764, -3.828888159743802, 0.5784497208988981, 1.504537880309263,
    0.9452301722972298, 0.48365298558929126, 2.331477296065598, -0.8246992982178993, 0.0428551961914488,
    1.6122202884181185, -0.7668881854915842, 1.6221489433902707, 1.553041387626076, 1.793948804763329,
    -1.4465807582514003, 2.5120433881491184
]
# the IR lookup table by increasing raw value: raw value -> distance (m)
RAWS = [
    67.19, 104.09, 120.0, 158.03, 234.93, 383.84, 601.46, 1465.73, 2133.33, 4095.0
]
DISTANCES = [
    0.07, 0.06, 0.05, 0.04, 0.03, 0.02, 0.015, 0.01, 0.005, 0.0
]
REACH = 0.06732496398373984  # m: the farthest a sensor tells something from nothing (its noise above the free value)
INPUTS = 8

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
motors = [robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor')]
for motor in motors:
    motor.setPosition(float('inf'))
    motor.setVelocity(0.0)
top_speed = motors[0].getMaxVelocity()
sensors = [robot.getDevice(f'ps{index}') for index in range(INPUTS)]
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
