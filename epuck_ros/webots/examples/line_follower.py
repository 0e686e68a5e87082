"""Line following on the ground-sensor extension: gs0 (left), gs1 (centre), gs2 (right) look at the floor.

A dark line reads lower than the white floor (Webots' infra-red rule: the red level of the floor scales the
distance the sensor sees). Each sensor's darkness (0 white .. 1 black, from the two levels measured at the start)
steers: the line under the left sensor turns the robot left, under the right one right. Lost, it turns towards
the side it last saw the line on.
Run: bringup --world line_track.yaml --lockstep, or webots_controller line_follower.py with a sim on that world.
"""
from controller import Robot

WHITE, BLACK = 987.0, 934.0   # the ground sensors 0.3 mm above a white floor and above black paint
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
    return min(1.0, max(0.0, (WHITE - value) / (WHITE - BLACK)))


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
