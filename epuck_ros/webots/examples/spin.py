"""Turn on the spot (the course's controller_2): wheels at +0.5 and -0.5 of the maximum speed.

The robot turns clockwise at R/L x (wR - wL) = 0.02/0.052 x (-6.28) = -2.415 rad/s.
Run: webots_controller spin.py
"""
from controller import Robot

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
left = robot.getDevice('left wheel motor')
right = robot.getDevice('right wheel motor')
top_speed = left.getMaxVelocity()
for motor, fraction in ((left, 0.5), (right, -0.5)):
    motor.setPosition(float('inf'))
    motor.setVelocity(fraction * top_speed)

while robot.step(step_ms) != -1:
    pass
