"""Sets the LEDs at every step: led0 counts the steps, led1..led9 their bits, so a recording shows any LED message
lost. The robot drives straight into the wall ahead and stays there, pushing; its ground sensors are read (a sense
on demand) but steer nothing."""
from controller import Robot

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
left, right = robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor')
for motor in (left, right):
    motor.setPosition(float('inf'))
    motor.setVelocity(6.0)
leds = [robot.getDevice(f'led{i}') for i in range(10)]
ground = [robot.getDevice(f'gs{i}') for i in range(3)]
for sensor in ground:
    sensor.enable(step_ms)
steps = 0
while robot.step(step_ms) != -1:
    steps += 1
    leds[0].set(steps)
    for bit, led in enumerate(leds[1:]):
        led.set(steps >> bit & 1)
