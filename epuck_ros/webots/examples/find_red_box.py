"""Find the red box with the camera: turn until red is in view, steer its centre to the image's middle, drive
up to it and stop in front of it (the front IR sensors say when it is close).

A pixel is red when its red channel is strong and the other two are weak; the image (52 x 39, BGRA bytes from
getImage) is read with Camera.imageGetRed/Green/Blue as in Webots. The body LED (led8) lights up once found.
Run: bringup --world coloured_objects.yaml --lockstep, or webots_controller find_red_box.py with a sim on it.
"""
from controller import Camera, Robot

FRONT, NEAR = (0, 7), 300.0   # front IR sensors, raw value of about 1.5 cm

robot = Robot()
step_ms = int(robot.getBasicTimeStep())
left = robot.getDevice('left wheel motor')
right = robot.getDevice('right wheel motor')
for motor in (left, right):
    motor.setPosition(float('inf'))
    motor.setVelocity(0.0)
top_speed = left.getMaxVelocity()
camera = robot.getDevice('camera')
camera.enable(step_ms)
width, height = camera.getWidth(), camera.getHeight()
proximity = [robot.getDevice(f'ps{i}') for i in FRONT]
for sensor in proximity:
    sensor.enable(step_ms)
body_led = robot.getDevice('led8')
found = False


def red_columns(image):
    """The columns with red pixels in the middle row band."""
    columns = []
    for x in range(width):
        for y in range(height // 3, 2 * height // 3):
            r = Camera.imageGetRed(image, width, x, y)
            g = Camera.imageGetGreen(image, width, x, y)
            b = Camera.imageGetBlue(image, width, x, y)
            if r > 150 and g < 90 and b < 90:
                columns.append(x)
                break
    return columns


while robot.step(step_ms) != -1:
    image = camera.getImage()
    if image is None or found:
        continue
    columns = red_columns(image)
    near = max(sensor.getValue() for sensor in proximity) > NEAR
    if columns and near:
        found = True
        left.setVelocity(0.0)
        right.setVelocity(0.0)
        body_led.set(1)
        print(f'found the red box at t={robot.getTime():.2f} s', flush=True)
    elif columns:
        offset = (sum(columns) / len(columns) - (width - 1) / 2) / (width / 2)   # -1 left edge .. 1 right edge
        left.setVelocity((0.4 + 0.3 * offset) * top_speed)
        right.setVelocity((0.4 - 0.3 * offset) * top_speed)
    else:
        left.setVelocity(-0.2 * top_speed)
        right.setVelocity(0.2 * top_speed)
