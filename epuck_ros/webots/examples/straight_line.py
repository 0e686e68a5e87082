"""Drive straight ahead at half speed (the course's controller_1): 0.5 x 6.28 rad/s x 0.02 m = 0.0628 m/s.

Run: webots_controller straight_line.py   (with `sim` running), or bringup --controller straight_line.py
"""
from controller import Robot

SPEED_FRACTION = 0.5

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
wheels = [robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor')]
for wheel in wheels:
    wheel.setPosition(float('inf'))  # velocity control
    wheel.setVelocity(SPEED_FRACTION * wheel.getMaxVelocity())

while robot.step(step_ms) != -1:
    pass  # the wheels keep the velocity they were given
