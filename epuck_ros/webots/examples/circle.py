"""Drive a circle (the course's controller_3): left wheel 0.3, right wheel 0.6 of the maximum speed.

Radius = L/2 x (wR + wL) / (wR - wL) = 0.026 x 0.9 / 0.3 = 0.078 m, counter-clockwise.
Run: webots_controller circle.py
"""
from controller import Robot

LEFT_FRACTION, RIGHT_FRACTION = 0.3, 0.6

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
left = robot.getDevice('left wheel motor')
right = robot.getDevice('right wheel motor')
left.setPosition(float('inf'))
right.setPosition(float('inf'))

while robot.step(step_ms) != -1:
    left.setVelocity(LEFT_FRACTION * left.getMaxVelocity())
    right.setVelocity(RIGHT_FRACTION * right.getMaxVelocity())
