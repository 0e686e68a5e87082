"""Line following on the ground-sensor extension: gs0 (left), gs1 (centre), gs2 (right) look at the floor.

A dark line reads lower than the white floor (Webots' infra-red rule: the red level of the floor scales the
distance the sensor sees): Webots' e-puck reads about 843 on white and 300 on black. The thresholds are the ones
Webots' own line demo (e-puck_line_demo.c) uses, so the program runs unchanged in Webots: above 800 is white floor,
below 500 the line. Each sensor's darkness (0 at 800 and above .. 1 at 500 and below) steers: the line under the
left sensor turns the robot left, under the right one right. Lost, it turns towards the side it last saw the line
on.
Run: bringup --controller line_follower.py --world line_track.yaml
"""
from controller import Robot

OFF_LINE, ON_LINE = 800.0, 500.0   # Webots' line demo: above LLM_THRESHOLD white, below LEM_THRESHOLD black
BASE, TURN = 0.35, 0.5        # fractions of the maximum wheel speed

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
left = robot.getDevice('left wheel motor')
right = robot.getDevice('right wheel motor')
for motor in (left, right):
    motor.setPosition(float('inf'))
    motor.setVelocity(0.0)
top_speed = left.getMaxVelocity()
ground = [robot.getDevice(f'gs{i}') for i in range(3)]
for sensor in ground:
    sensor.enable(step_ms)
last_side = 1.0   # +1: the line was last seen on the left


def darkness(value):
    return min(1.0, max(0.0, (OFF_LINE - value) / (OFF_LINE - ON_LINE)))


while robot.step(step_ms) != -1:
    values = [sensor.getValue() for sensor in ground]
    if values[0] != values[0]:   # NaN: no reading before the first sampling period
        continue
    dark_left, dark_centre, dark_right = (darkness(v) for v in values)
    if dark_left + dark_centre + dark_right < 0.2:
        steer = last_side   # lost: turn on the spot towards where the line was
        speed = 0.0
    else:
        steer = dark_left - dark_right
        if abs(steer) > 0.2:
            last_side = 1.0 if steer > 0 else -1.0
        speed = BASE
    left.setVelocity((speed - TURN * steer) * top_speed)
    right.setVelocity((speed + TURN * steer) * top_speed)
