"""A "rectangle" on a timer (the course's controller_4): 5 s straight, then 1 s turning left on the spot.

Nothing measures the turn: 1 s at -0.3 / +0.3 of the maximum speed turns about 83 degrees, not 90, so the
figure does not close (the `rectangle` behaviour node has a closed-loop mode that does). Each phase ends on the
step nearest its duration, as the `rectangle` node's timed mode does: a turn is 31 steps of 32 ms (82.4
degrees). The course's `elapsed_time >= TURN_TIME` keeps turning until 1.024 s, one step more (85.0 degrees).
Run: webots_controller timed_rectangle.py
"""
from controller import Robot

STRAIGHT_SECONDS, TURN_SECONDS = 5.0, 1.0
STRAIGHT, TURN = (0.5, 0.5), (-0.3, 0.3)  # (left, right) fractions of the maximum speed

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
half_step = step_ms / 2000.0  # seconds
motors = (robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor'))
for motor in motors:
    motor.setPosition(float('inf'))


def drive(fractions):
    for motor, fraction in zip(motors, fractions):
        motor.setVelocity(fraction * motor.getMaxVelocity())


turning = False
phase_began = robot.getTime()
while robot.step(step_ms) != -1:
    now = robot.getTime()
    if now - phase_began >= (TURN_SECONDS if turning else STRAIGHT_SECONDS) - half_step:
        turning = not turning
        phase_began = now
    drive(TURN if turning else STRAIGHT)
