"""The senses through the real `sim` process over DDS: the three examples run unchanged by `webots_controller`
(lockstep, real_time_factor 0), judged on ground_truth; the sense topics' messages against the core.
The shim devices' own semantics (no DDS) are checked against Webots' reference manual."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from sensor_msgs.msg import CameraInfo, Image, Imu
from std_msgs.msg import Float64MultiArray

from conftest import ros_args
from epuck_ros.model import ACCELEROMETER_LOOKUP_TABLE, CAMERA_FOV, GYRO_LOOKUP_TABLE, LIGHT_LOOKUP_TABLE
from epuck_ros.webots.devices import Accelerometer, Camera, Gyro, LightSensor, png_bytes
from test_webots import ControllerRun, example

WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'


# --- devices, no DDS ----------------------------------------------------------------------------------------------

def test_camera_device_hands_out_images_as_webots_does(capsys: pytest.CaptureFixture, tmp_path: Path) -> None:
    now = [0]
    camera = Camera('camera', lambda: now[0], 4, 3, CAMERA_FOV, 0.0055)
    assert camera.getImage() is None
    assert 'wb_camera_get_image() called for a disabled device' in capsys.readouterr().err
    camera.enable(32)
    rgb = np.arange(4 * 3 * 3, dtype=np.uint8).reshape(3, 4, 3)
    camera.sample(16_000_000, rgb)
    assert camera.getImage() is None                     # the first image after one sampling period
    camera.sample(32_000_000, rgb)
    image = camera.getImage()
    assert len(image) == 4 * 3 * 4                       # BGRA, 4 bytes a pixel, row by row
    assert list(image[:4]) == [2, 1, 0, 255]             # pixel (0, 0): blue, green, red, alpha
    x, y = 3, 2
    assert Camera.imageGetRed(image, 4, x, y) == rgb[y, x, 0] and Camera.imageGetBlue(image, 4, x, y) == rgb[y, x, 2]
    assert Camera.imageGetGreen(image, 4, x, y) == rgb[y, x, 1]
    assert Camera.imageGetGray(image, 4, x, y) == int(rgb[y, x].sum()) // 3
    array = camera.getImageArray()
    assert len(array) == 4 and len(array[0]) == 3 and array[x][y] == rgb[y, x].tolist()   # image[x][y][channel]
    assert (camera.getWidth(), camera.getHeight(), camera.getFov()) == (4, 3, CAMERA_FOV)
    assert camera.saveImage(str(tmp_path / 'a.png'), 100) == 0
    assert (tmp_path / 'a.png').read_bytes() == png_bytes(rgb)
    assert (tmp_path / 'a.png').read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert camera.saveImage(str(tmp_path / 'a.bmp'), 100) == -1
    assert camera.saveImage(str(tmp_path / 'no' / 'a.png'), 100) == -1
    assert camera.saveImage(str(tmp_path / 'a.jpg'), 90) == -1 and 'JPEG' in capsys.readouterr().err


def test_png_is_readable_by_matplotlib(tmp_path: Path) -> None:
    import matplotlib.image
    rgb = (np.random.default_rng(0).random((39, 52, 3)) * 255).astype(np.uint8)
    (tmp_path / 'b.png').write_bytes(png_bytes(rgb))
    assert (np.round(matplotlib.image.imread(tmp_path / 'b.png')[..., :3] * 255).astype(np.uint8) == rgb).all()


def test_light_accelerometer_and_gyro_devices(capsys: pytest.CaptureFixture) -> None:
    light = LightSensor('ls0', lambda: 0, LIGHT_LOOKUP_TABLE)
    assert light.getLookupTable() == [1.0, 4095.0, 0.01, 2.0, 0.0, 0.01]
    light.enable(32)
    assert math.isnan(light.getValue())
    light.sample(32_000_000, 1234.5)
    assert light.getValue() == 1234.5
    accelerometer = Accelerometer('accelerometer', lambda: 0, ACCELEROMETER_LOOKUP_TABLE)
    values = accelerometer.getValues()
    assert all(math.isnan(v) for v in values) and 'wb_accelerometer_get_values() called for a disabled' in \
        capsys.readouterr().err
    accelerometer.enable(64)
    accelerometer.sample(32_000_000, (0.0, 0.0, 9.81))
    assert all(math.isnan(v) for v in accelerometer.getValues())     # one sampling period (64 ms) not yet over
    accelerometer.sample(64_000_000, (0.1, 0.2, 9.81))
    assert accelerometer.getValues() == [0.1, 0.2, 9.81] and accelerometer.getSamplingPeriod() == 64
    gyro = Gyro('gyro', lambda: 0, GYRO_LOOKUP_TABLE)
    assert gyro.getLookupTable()[:3] == [-13.315805, -100000.0, 0.003]
    with pytest.raises(AttributeError, match='Gyro supports'):
        gyro.getValue()


# --- processes ----------------------------------------------------------------------------------------------------

def test_line_follower_example_follows_the_line_track(launch: object, test_node: object) -> None:
    run = ControllerRun(launch, test_node, example('line_follower'), 12.0, world=WORLDS / 'line_track.yaml')
    rows = run.finish()
    off_line = np.abs(np.hypot(rows[:, 1] / 0.35, rows[:, 2] / 0.25) - 1.0) * 0.25   # ~m from the oval
    travelled = np.hypot(*np.diff(rows[:, 1:3], axis=0).T).sum()
    print(f'line_follower: {travelled:.3f} m in 12 s, farthest {off_line.max() * 1000:.1f} mm off the oval')
    assert travelled > 0.45 and off_line.max() < 0.015   # 0.044 m/s: well over a quarter of the oval
    assert run.stop_controller() == 0, run.output


def test_find_red_box_example_stops_at_the_red_box(launch: object, test_node: object) -> None:
    run = ControllerRun(launch, test_node, example('find_red_box'), 16.0, world=WORLDS / 'coloured_objects.yaml')
    rows = run.finish()
    x, y, yaw = rows[-1, 1:4]
    bearing = math.atan2(0.25 - y, 0.3 - x) - yaw
    print(f'find_red_box: ends at ({x:.3f}, {y:.3f}), {math.hypot(0.3 - x, 0.25 - y):.3f} m from the red box, '
          f'bearing {math.degrees(bearing):.1f} deg')
    assert math.hypot(0.3 - x, 0.25 - y) < 0.15 and abs(math.remainder(bearing, math.tau)) < 0.6
    assert 'found the red box' in run.output
    assert run.stop_controller() == 0, run.output


def test_light_seeker_example_drives_towards_the_light(launch: object, tmp_path: Path) -> None:
    """The Braitenberg light seeker through `bringup --controller` in lockstep, recorded (bringup resumes the run
    only once the recorder is subscribed, and closes the bag before the simulator goes: every step is in it): it
    starts facing away from the lit arena's light, turns until its side sensors see it (drifting away meanwhile) and
    ends near it, as headless (test_senses.py)."""
    from epuck_ros.bag.reader import Bag
    from epuck_ros.bag.run_summary import load_runs
    duration, light = 40.0, (0.25, 0.25)
    run = launch('bringup', '--controller', str(example('light_seeker')), '--world', str(WORLDS / 'lit_arena.yaml'),
                 '--duration', str(duration), '--real-time-factor', '0', '--no-noise',
                 '--record', str(tmp_path / 'run'))
    assert run.proc.wait(timeout=240) == 0, run.output()
    with Bag(tmp_path / 'run') as bag:
        [recorded] = load_runs(bag)
    truth = recorded.truth
    start, end = (math.dist(light, (truth.x[i], truth.y[i])) for i in (0, -1))
    print(f'light_seeker: {start:.3f} m from the light at t={truth.t[0]:.3f} s, {end:.3f} m at {truth.t[-1]:.3f} s')
    assert truth.t[-1] - truth.t[0] == pytest.approx(duration, abs=0.1)
    assert (truth.x[0], truth.y[0]) == pytest.approx((-0.2, -0.2), abs=0.01) and end < 0.15 < start


def test_sense_topics_carry_the_cores_readings(launch: object, test_node: object) -> None:
    """Subscribers on every sense topic make the sim compute them; the messages match the core's readings."""
    from epuck_ros.simulation import Simulation
    from epuck_ros.world import load_world
    world = WORLDS / 'lit_arena.yaml'
    images = test_node.collect(Image, 'camera/image_raw', 100)
    infos = test_node.collect(CameraInfo, 'camera/camera_info', 100)
    ground = test_node.collect(Float64MultiArray, 'ground_raw', 100)
    light = test_node.collect(Float64MultiArray, 'light_raw', 100)
    imus = test_node.collect(Imu, 'imu', 100)
    launch('sim', *ros_args({'world': str(world), 'real_time_factor': 0.0, 'noise': False}))
    test_node.wait_for_simulator()
    test_node.spin_until(lambda: images and infos and ground and light and imus, timeout=30.0,
                         what='the sense topics')   # no command: the robot stands still, every step reads the same
    core = Simulation(load_world(world), noise=False)
    for kind in ('camera', 'ground', 'light', 'imu'):
        core.senses.want(kind, [0])
    image = images[-1]
    assert (image.width, image.height, image.encoding, image.step) == (52, 39, 'rgb8', 156)
    assert (np.frombuffer(bytes(image.data), dtype=np.uint8).reshape(39, 52, 3) == core.senses.images[0]).all()
    assert list(ground[-1].data) == core.senses.ground_raw[0].tolist()
    assert list(light[-1].data) == pytest.approx(core.senses.light_raw[0].tolist(), rel=1e-12)
    assert imus[-1].orientation_covariance[0] == -1.0 and imus[-1].linear_acceleration.z == pytest.approx(9.81)
    focal = 26 / math.tan(CAMERA_FOV / 2)
    assert list(infos[-1].k) == pytest.approx([focal, 0, 25.5, 0, focal, 19, 0, 0, 1])
    assert infos[-1].header.frame_id == image.header.frame_id == 'camera'


def test_view_shows_the_selected_robots_camera_and_the_leds(launch: object, test_node: object,
                                                            tmp_path: Path) -> None:
    """A page looking at the robot: the view subscribes its camera (the sim renders it) and serves it as a PNG;
    the LED values a controller publishes reach the page's state."""
    import http.client
    import json

    import matplotlib.image
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from std_msgs.msg import Int32MultiArray

    from epuck_ros.simulation import Simulation
    from epuck_ros.world import load_world
    from test_view_node import _url

    world = WORLDS / 'coloured_objects.yaml'
    launch('sim', *ros_args({'world': str(world), 'noise': False, 'real_time_factor': 5.0}))
    address = _url(launch('view', '--ros-args', '-p', 'port:=0'))
    leds = test_node.node.create_publisher(Int32MultiArray, 'leds', QoSProfile(
        depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))
    leds.publish(Int32MultiArray(data=[1, 0, 0, 0, 0, 0, 0, 0, 1, 0]))

    def get(path: str) -> tuple[int, bytes]:
        connection = http.client.HTTPConnection(*address, timeout=30)
        connection.request('GET', path)
        response = connection.getresponse()
        result = response.status, response.read()
        connection.close()
        return result

    def state() -> dict:
        status, body = get('/state?robot=epuck')
        return json.loads(body)['robots'].get('epuck', {}) if status == 200 else {}
    test_node.spin_until(lambda: state().get('camera') is not None and state().get('leds') is not None,
                         what='the camera image and the LEDs in the view', timeout=60)
    assert state()['leds'] == [1, 0, 0, 0, 0, 0, 0, 0, 1, 0]
    status, png = get('/camera?robot=epuck')
    assert status == 200 and png[:8] == b'\x89PNG\r\n\x1a\n'
    path = tmp_path / 'view_camera.png'
    path.write_bytes(png)
    pixels = np.round(matplotlib.image.imread(path)[..., :3] * 255).astype(np.uint8)
    core = Simulation(load_world(world), noise=False)
    core.senses.want('camera', [0])
    assert (pixels == core.senses.images[0]).all()   # no command: the robot stands at its start
    assert get('/camera?robot=nobody')[0] == 404


def test_senses_parameter_and_camera_size(launch: object, test_node: object) -> None:
    """`senses` computes a sense with no subscriber; camera_width/height give bigger images with their K; an
    unknown sense is one line and exit code 2."""
    images = test_node.collect(Image, 'camera/image_raw', 10)
    infos = test_node.collect(CameraInfo, 'camera/camera_info', 10)
    launch('sim', *ros_args({'real_time_factor': 0.0, 'senses': 'ground', 'camera_width': 104,
                             'camera_height': 78}))
    test_node.wait_for_simulator()
    test_node.spin_until(lambda: images and infos, what='a 104 x 78 image', timeout=30.0)
    assert (images[-1].width, images[-1].height, len(images[-1].data)) == (104, 78, 104 * 78 * 3)
    focal = 52 / math.tan(CAMERA_FOV / 2)
    assert list(infos[-1].k) == pytest.approx([focal, 0, 51.5, 0, focal, 38.5, 0, 0, 1])
    wrong = launch('sim', *ros_args({'senses': 'camera,smell'}))
    assert wrong.proc.wait(timeout=30) == 2
    assert wrong.output().strip().splitlines()[-1] == \
        "sim: cannot start: senses: unknown sense 'smell' (senses: camera, ground, light, imu, tof)"


CAMERA_SIZE_SCRIPT = """
from controller import Camera, Robot
robot = Robot()
camera = robot.getDevice('camera')
camera.enable(32)
print(f'enabled {camera.getWidth()} x {camera.getHeight()}', flush=True)
while robot.step(32) != -1:
    image = camera.getImage()
    if image is not None:
        width, height = camera.getWidth(), camera.getHeight()
        array = camera.getImageArray()
        red = Camera.imageGetRed(image, width, width - 1, height - 1) == array[width - 1][height - 1][0]
        print(f'camera {width} x {height}: {len(image)} bytes, {len(array)} x {len(array[0])}, {red}', flush=True)
        break
while robot.step(32) != -1:
    pass
"""


def test_a_controllers_camera_has_the_sims_camera_size(launch: object, test_node: object, tmp_path: Path) -> None:
    """With the sim's camera_width/height at 104 x 78, a Webots controller's camera hands out 104 x 78 images and
    says so (getWidth/getHeight, the BGRA buffer, the image array), as its camera_info does."""
    script = tmp_path / 'camera_size.py'
    script.write_text(CAMERA_SIZE_SCRIPT)
    run = ControllerRun(launch, test_node, script, 0.5, sim_params={'camera_width': 104, 'camera_height': 78})
    run.finish()
    assert 'enabled 104 x 78' in run.output and 'camera 104 x 78: 32448 bytes, 104 x 78, True' in run.output, \
        run.output
    assert run.stop_controller() == 0, run.output
    from epuck_ros.webots.link import SimLink
    link = SimLink('camera_size_probe', '', lambda: False)   # what a Robot can build its camera with
    try:
        assert link.connect() == pytest.approx(0.032) and link.camera_size == (104, 78)
    finally:
        link.close()
