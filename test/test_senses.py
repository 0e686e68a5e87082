"""The senses beyond the IR ring, pure core: camera geometry and colours, ground sensors against the lookup table,
light sensors facing, facing away and in shadow, the IMU spinning at the course's 2.415 rad/s, world appearance
parsing (old worlds unchanged, bad fields named), separate noise streams."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from epuck_ros.world.appearance import BOX_COLOR, FLOOR_COLOR, SKY_COLOR, WALL_COLOR, Appearance, read_appearance
from epuck_ros.model import (
    CAMERA_FOV, CAMERA_POSE, GROUND_LOOKUP_TABLE, GROUND_SENSOR_POSES, GYRO_LOOKUP_TABLE, RobotModel)
from epuck_ros.sensors import imu
from epuck_ros.sensors.camera import Camera
from epuck_ros.sensors.ground import FLOOR_ROUGHNESS, GroundSensors
from epuck_ros.sensors.light import LightSensors
from epuck_ros.sensors.lookup import sensor_rng
from epuck_ros.sensors.scene import Scene
from epuck_ros.world import Box, World, WorldError, load_world, world_from_dict
from epuck_ros.world.loading import _FieldReader

WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'
RED = (1.0, 0.0, 0.0)


def appearance(top: dict) -> Appearance:
    return read_appearance(_FieldReader('test.yaml'), top)


def red_box_scene(distance: float, width: float = 0.1) -> Scene:
    """A red box whose near face is `distance` m in front of the camera of a robot at the origin facing +x."""
    centre = CAMERA_POSE[0] + distance + 0.05
    world = World(arena_size=(2.0, 2.0), boxes=[Box(centre, 0.0, 0.1, width)])
    return Scene(world, appearance({'boxes': [{'color': list(RED)}]}))


def red_columns(image: np.ndarray, row: int) -> np.ndarray:
    pixels = image[row]
    return np.flatnonzero((pixels[:, 0] == 255) & (pixels[:, 1] == 0) & (pixels[:, 2] == 0))


@pytest.mark.parametrize('distance, width', [(0.2, 0.1), (0.4, 0.1), (0.3, 0.05)])
def test_camera_box_covers_the_columns_the_field_of_view_gives(distance: float, width: float) -> None:
    camera = Camera(red_box_scene(distance, width))
    image = camera.render(np.zeros((1, 3)))[0]
    columns = red_columns(image, camera.height // 2)
    # pinhole: the face spans +-width/2 at `distance`; column c's centre looks at tan = (26 - c - 0.5) / f
    focal = 26 / math.tan(CAMERA_FOV / 2)
    expected = [c for c in range(52) if abs((26 - c - 0.5) / focal) <= width / 2 / distance]
    assert columns.tolist() == expected
    assert abs(len(columns) - 2 * focal * width / 2 / distance) <= 1.0


def test_camera_turning_moves_the_box_by_the_computed_columns() -> None:
    camera = Camera(red_box_scene(0.3, 0.02))
    straight = red_columns(camera.render(np.zeros((1, 3)))[0], 19)
    turn = 0.1   # turning left moves the world to the right of the image
    turned = red_columns(camera.render(np.array([[0.0, 0.0, turn]]))[0], 19)
    # the camera sits 0.03 m ahead of the turning axis: the box's bearing from the turned camera
    cx, cy = CAMERA_POSE[0] * math.cos(turn), CAMERA_POSE[0] * math.sin(turn)
    bearing = math.atan2(0.0 - cy, CAMERA_POSE[0] + 0.3 - cx) - turn
    focal = 26 / math.tan(CAMERA_FOV / 2)
    expected_column = 26 - 0.5 - focal * math.tan(bearing)
    assert turned.mean() == pytest.approx(expected_column, abs=1.0)
    assert turned.mean() - straight.mean() == pytest.approx(focal * math.tan(turn), abs=1.5)


def test_camera_sees_sky_walls_floor_and_floor_paint() -> None:
    world = World(arena_size=(1.0, 1.0))
    scene = Scene(world, appearance({'floor': {'paint': [{'disc': [0.15, 0.0], 'radius': 0.03, 'color': [0, 0, 1]}]}}))
    camera = Camera(scene)
    image = camera.render(np.zeros((1, 3)))[0]
    to_u8 = lambda color: (np.round(np.array(color) * 255)).astype(np.uint8).tolist()  # noqa: E731
    assert image[0, 26].tolist() == to_u8(SKY_COLOR)            # the wall (0.1 m at 0.47 m) ends below the top row
    assert image[18, 26].tolist() == to_u8(WALL_COLOR)          # just above the horizon: the wall ahead
    assert image[38, 0].tolist() == to_u8(FLOOR_COLOR)          # the white floor close by
    # the blue disc 0.15 m ahead: the row looking down at 0.12 m from the camera (0.028 m high)
    row = round(19.5 + (26 / math.tan(CAMERA_FOV / 2)) * CAMERA_POSE[2] / 0.12 - 0.5)
    assert image[row, 26].tolist() == [0, 0, 255]
    default = Camera(Scene(World(boxes=[Box(0.3, 0.0, 0.1, 0.1)]))).render(np.zeros((1, 3)))[0]
    assert default[19, 26].tolist() == to_u8(BOX_COLOR)


def test_camera_sees_other_robots_and_not_its_own_body() -> None:
    world = World(arena_size=(2.0, 2.0))
    camera = Camera(Scene(world))
    poses = np.array([[0.0, 0.0, 0.0], [0.3, 0.0, math.pi]])
    alone = camera.render(poses[:1])[0]
    together = camera.render(poses, robots_xy=poses[:, :2])
    assert not (alone[19] == together[0][19]).all()
    body = np.round(np.array(Scene(world).colors[-1]) * 255).astype(np.uint8)
    assert (together[0][19, 26] == body).all() and (together[1][19, 26] == body).all()


def ground_world(paint: list) -> Scene:
    return Scene(World(), appearance({'floor': {'paint': paint}}))


def test_ground_sensors_over_a_line_and_over_the_white_floor_follow_webots_rule() -> None:
    line = {'polyline': [[-0.5, 0.0], [0.5, 0.0]], 'width': 0.012, 'color': [0, 0, 0]}
    sensors = GroundSensors(ground_world([line]))
    height = GROUND_SENSOR_POSES[0, 2]
    table = GROUND_LOOKUP_TABLE

    def expected(red: float) -> float:   # distance / (0.2 + 0.8 red (1 - 0.5 roughness)), then the table
        return float(np.interp(height / (0.2 + 0.8 * red * (1 - 0.5 * FLOOR_ROUGHNESS)), table[:, 0], table[:, 1]))
    over_line = sensors.read(np.array([[0.0, 0.0, 0.0]]), None)[0]        # gs1 on the line, gs0 / gs2 beside it
    assert over_line[1] == pytest.approx(expected(0.0))
    assert over_line[0] == pytest.approx(expected(1.0)) and over_line[2] == pytest.approx(expected(1.0))
    assert over_line[1] < 500 < 800 < over_line[0]   # Webots' line demo: below 500 the line, above 800 white
    crossing = sensors.read(np.array([[0.0, -0.03, math.pi / 2]]), None)[0]   # facing +y: all three on the line
    assert crossing == pytest.approx([expected(0.0)] * 3)
    white = sensors.read(np.array([[0.0, 0.3, 0.0]]), None)[0]
    assert white == pytest.approx([expected(1.0)] * 3)
    red = GroundSensors(ground_world([{**line, 'color': [1, 0, 0]}])).read(np.zeros((1, 3)), None)[0]
    assert red[1] == pytest.approx(expected(1.0))   # infra-red: a red line reads like white, as in Webots
    noisy = sensors.read(np.tile([0.0, 0.3, 0.0], (2000, 1)), sensor_rng(0, 'ground'))
    white_distance = height / (0.2 + 0.8 * (1 - 0.5 * FLOOR_ROUGHNESS))
    assert noisy.std() / noisy.mean() == pytest.approx(float(np.interp(white_distance, table[:, 0], table[:, 2])),
                                                       rel=0.1)


def light_scene(boxes: list[Box] = (), heights: list[float] = ()) -> Scene:
    world = World(arena_size=(2.0, 2.0), boxes=boxes)
    top = {'lights': [{'position': [0.5, 0.0, 0.05], 'intensity': 0.2}],
           'boxes': [{'height': h} for h in heights]}
    return Scene(world, appearance(top))


def test_light_sensors_facing_away_and_in_shadow() -> None:
    sensors = LightSensors(light_scene())
    facing = sensors.irradiance(np.zeros((1, 3)))[0]
    # ls0 / ls7 look 0.3 rad either side of ahead; the light 0.47 m away: E = I cos / d^2
    for index in (0, 7):
        dx, dy = 0.5 - (0.03), 0.0 - (-0.01 if index == 0 else 0.01)
        dz = 0.05 - 0.0329
        d2 = dx * dx + dy * dy + dz * dz
        yaw = -0.3008 if index == 0 else 0.2992
        cos = (math.cos(yaw) * dx + math.sin(yaw) * dy) / math.sqrt(d2)
        assert facing[index] == pytest.approx(0.2 * cos / d2)
    assert facing[3] == facing[4] == 0.0
    away = sensors.irradiance(np.array([[0.0, 0.0, math.pi]]))[0]
    assert away[0] == away[7] == 0.0 and away[3] > 0.0 and away[4] > 0.0
    closer = np.array([[0.15, 0.0, 0.0]])
    raw = sensors.read(closer, None)[0]
    assert raw == pytest.approx(np.interp(sensors.irradiance(closer)[0], [1.0, 2.0], [4095.0, 0.0]))
    assert raw[3] == 4095.0 and 0.0 < raw[0] < 4095.0   # dark reads 4095, more light less
    tall = LightSensors(light_scene([Box(0.25, 0.0, 0.05, 0.3)], [0.1])).irradiance(np.zeros((1, 3)))[0]
    assert tall.max() == 0.0                          # the box hides the light
    low = LightSensors(light_scene([Box(0.25, 0.0, 0.05, 0.3)], [0.02])).irradiance(np.zeros((1, 3)))[0]
    assert low == pytest.approx(facing)               # a box below the sight line does not
    robots = np.array([[0.0, 0.0], [0.25, 0.0]])
    shadowed = sensors.irradiance(np.zeros((1, 3)), robots_xy=robots, own=np.array([0]))[0]
    assert shadowed[0] == shadowed[7] == 0.0          # another robot's body between


def test_imu_while_spinning_at_the_course_rate() -> None:
    from epuck_ros.simulation import Simulation
    sim = Simulation(World(), noise=False)
    rate = 2.415
    sim.command_twist(0, 0.0, rate)
    sim.step()
    previous = sim.true_twist.copy()
    sim.command_twist(0, 0.0, rate)
    sim.step()
    twist = sim.true_twist
    gyro = imu.gyro_values(imu.angular_velocity(twist), None)[0]
    assert gyro[:2].tolist() == [0.0, 0.0]
    assert gyro[2] == pytest.approx(rate * GYRO_LOOKUP_TABLE[1, 1] / GYRO_LOOKUP_TABLE[1, 0], rel=1e-9)
    assert imu.rates_from_gyro_values(gyro)[2] == pytest.approx(rate)
    accel = imu.accelerometer_values(imu.acceleration(twist, previous, sim.time_step), None)[0]
    assert accel == pytest.approx([0.0, 0.0, imu.GRAVITY], abs=1e-12)   # turning in place: no linear acceleration
    arc = np.array([[0.1, rate]])
    assert imu.acceleration(arc, arc, 0.032)[0, 1] == pytest.approx(0.1 * rate)   # centripetal v w, to the left
    noisy = imu.gyro_values(np.tile([0.0, 0.0, rate], (4000, 1)), sensor_rng(3, 'gyro'))[:, 2]
    assert noisy.std() / noisy.mean() == pytest.approx(0.003, rel=0.1)


def test_noise_streams_are_separate() -> None:
    values = [sensor_rng(5, kind).standard_normal(3).tolist() for kind in ('ground', 'light', 'accelerometer', 'gyro')]
    assert len({tuple(v) for v in values}) == 4
    assert sensor_rng(5, 'ground').standard_normal(3).tolist() == values[0]
    assert np.random.default_rng(5).standard_normal(3).tolist() not in values   # the IR stream stays its own


def test_appearance_defaults_and_fields() -> None:
    plain = appearance({})
    assert plain == Appearance()
    top = {'arena': {'color': [0, 1, 0], 'height': 0.05}, 'boxes': [{'color': [1, 0, 0]}, {'height': 0.02}],
           'floor': {'color': [0.9, 0.9, 0.9],
                     'paint': [{'polygon': [[0, 0], [0.1, 0], [0, 0.1]], 'color': [1, 1, 0]}]},
           'lights': [{'position': [0, 0, 0.3]}]}
    parsed = appearance(top)
    assert parsed.wall_color == (0.0, 1.0, 0.0) and parsed.wall_height == 0.05
    assert parsed.box_color(0) == RED and parsed.box_height(1) == 0.02 and parsed.box_color(1) == BOX_COLOR
    assert parsed.paint[0].kind == 'polygon' and parsed.lights[0].intensity == 1.0


@pytest.mark.parametrize('top, field', [
    ({'arena': {'color': [1, 2, 0]}}, 'arena.color[1]'),
    ({'boxes': [{'height': -1}]}, 'boxes[0].height'),
    ({'floor': {'paint': [{'polyline': [[0, 0]], 'width': 0.01}]}}, 'floor.paint[0].polyline'),
    ({'floor': {'paint': [{'polyline': [[0, 0], [1, 1]]}]}}, 'floor.paint[0].width'),
    ({'floor': {'paint': [{'disc': [0, 0], 'radius': 0.1, 'width': 1}]}}, 'floor.paint[0].width'),
    ({'floor': {'paint': [{'disc': [0, 0]}]}}, 'floor.paint[0].radius'),
    ({'floor': {'paint': [{'circle': [0, 0]}]}}, 'floor.paint[0]'),
    ({'floor': {'tiles': 1}}, 'floor'),
    ({'lights': [{'position': [0, 0]}]}, 'lights[0].position'),
    ({'lights': [{'position': [0, 0, 1], 'intensity': -1}]}, 'lights[0].intensity'),
    ({'lights': 'sun'}, 'lights'),
])
def test_bad_appearance_is_refused_naming_the_field(top: dict, field: str) -> None:
    with pytest.raises(WorldError) as error:
        appearance(top)
    assert str(error.value).startswith(f'test.yaml: {field}: ')


def test_floor_texture_paints_in_order() -> None:
    scene = ground_world([{'disc': [0.0, 0.0], 'radius': 0.1, 'color': [1, 0, 0]},
                          {'polygon': [[-0.05, -0.05], [0.05, -0.05], [0.05, 0.05], [-0.05, 0.05]],
                           'color': [0, 1, 0]}])
    floor = scene.floor
    at = lambda x, y: floor.flat[floor.index(np.array(x), np.array(y))].tolist()  # noqa: E731
    assert at(0.0, 0.0) == [0.0, 1.0, 0.0] and at(0.08, 0.0) == [1.0, 0.0, 0.0] and at(0.3, 0.3) == [1.0, 1.0, 1.0]
    assert RobotModel() == RobotModel()   # the model's new constants left the dataclass as it was


def test_simulation_reads_a_sense_only_while_wanted_and_ir_stays_the_same() -> None:
    from epuck_ros.simulation import Simulation
    world = load_world(WORLDS / 'default.yaml')

    def run(kinds: tuple[str, ...]) -> tuple[Simulation, list[np.ndarray]]:
        sim = Simulation(world, seed=3)
        for kind in kinds:
            sim.senses.want(kind, [0])
        ir = []
        for step in range(40):
            sim.command_wheels(0, 3.0, 2.0)
            sim.step()
            ir.append(sim.ir_raw.copy())
        return sim, ir
    plain, plain_ir = run(())
    assert not plain.senses.active and np.isnan(plain.senses.ground_raw).all() and plain.senses.images is None
    assert np.isnan(plain.senses.tof).all()
    every, every_ir = run(('camera', 'ground', 'light', 'imu', 'tof'))
    assert all((a == b).all() for a, b in zip(plain_ir, every_ir))
    assert (plain.true_pose == every.true_pose).all()
    ground_only, _ = run(('ground',))
    assert (ground_only.senses.ground_raw == every.senses.ground_raw).all()   # its own noise stream
    assert every.senses.images[0].any() and np.isfinite(every.senses.light_raw).all()
    assert every.senses.accelerometer[0, 2] == pytest.approx(9.81, rel=0.02)
    readings = every.senses.readings_of(0)   # what a headless Webots controller's step is handed
    assert sorted(readings) == ['camera', 'ground', 'imu', 'light', 'tof'] and readings['camera'].shape == (39, 52, 3)
    assert readings['tof'] == pytest.approx(float(every.senses.tof[0]), rel=1e-6)
    assert readings['imu'][1] == tuple(every.senses.gyro[0].tolist()) and ground_only.senses.readings_of(0).keys() \
        == {'ground'}


def test_world_files_with_appearance_round_trip_and_old_worlds_are_unchanged() -> None:
    for path in sorted(WORLDS.glob('*.yaml')):
        world = load_world(path)
        text = path.read_text()
        if not any(key in text for key in ('color', 'floor', 'lights', 'height')):
            assert world.appearance == Appearance()
            assert set(world.to_dict()) <= {'arena', 'boxes', 'cylinders', 'robot', 'robots'}
        assert world_from_dict(world.to_dict()) == world
    data = {'arena': {'size': [1, 1], 'color': [0, 0, 1]}, 'boxes': [{'position': [0.2, 0], 'size': [0.1, 0.1],
                                                                     'color': [1, 0, 0], 'height': 0.05}],
            'floor': {'paint': [{'disc': [0, 0.3], 'radius': 0.05, 'color': [0, 1, 0]}]},
            'lights': [{'position': [0, 0, 0.5], 'intensity': 2.0}]}
    world = world_from_dict(data)
    assert world.appearance.box_color(0) == RED and world_from_dict(world.to_dict()) == world


def test_reset_reads_the_senses_at_the_start_again() -> None:
    from epuck_ros.simulation import Simulation
    sim = Simulation(load_world(WORLDS / 'line_track.yaml'), noise=False)
    sim.senses.want('ground', [0])
    sim.senses.want('imu', [0])
    at_start = sim.senses.ground_raw.copy()
    for _ in range(30):
        sim.command_wheels(0, 6.0, 6.0)
        sim.step()
    assert (sim.senses.ground_raw != at_start).any()
    sim.reset()
    assert (sim.senses.ground_raw == at_start).all()
    assert sim.senses.accelerometer[0].tolist() == pytest.approx([0.0, 0.0, 9.81], abs=1e-12)   # from rest


def test_isolated_robots_do_not_see_each_other() -> None:
    from epuck_ros.simulation import Simulation
    from epuck_ros.world.data import RobotStart
    world = World(arena_size=(2.0, 2.0), robots=[RobotStart('a', 0.0, 0.0, 0.0), RobotStart('b', 0.3, 0.0, math.pi)])
    shared, isolated = Simulation(world, noise=False), Simulation(world, noise=False, isolated=True)
    for sim in (shared, isolated):
        sim.senses.want('camera', [0, 1])
    alone = Simulation(world.with_robots(world.robots[:1]), noise=False)
    alone.senses.want('camera', [0])
    assert (isolated.senses.images[0] == alone.senses.images[0]).all()
    assert not (shared.senses.images[0] == alone.senses.images[0]).all()


# --- the three examples headless (issue 20: over ROS in test_senses_ros.py, headless here) --------------------

EXAMPLES = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples'
WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'


def headless_row(example: str, world: str, duration: float) -> dict:
    """The one robot's row of `example` run headless on `world` (a trial in a process of its own, no ROS)."""
    from epuck_ros.experiments.trial import Script, Trial, run_trial
    [row] = run_trial(Trial(Script(str(EXAMPLES / example)), world=str(WORLDS / world), duration=duration))
    assert row['error'] == '', row['error']
    return row


def test_the_sense_examples_do_their_jobs_headless():
    """The line follower stays on its track without touching anything, the light seeker ends near the light, the
    red-box finder ends close to the red box: each reading its senses through the shim bound to the core."""
    follower = headless_row('line_follower.py', 'line_track.yaml', 20.0)
    assert follower['distance_m'] > 0.5 and follower['contacts_obstacles'] == 0
    lit = load_world(WORLDS / 'lit_arena.yaml')
    light = np.array([lit.appearance.lights[0].x, lit.appearance.lights[0].y])
    start = np.array(lit.start_pose[:2])
    seeker = headless_row('light_seeker.py', 'lit_arena.yaml', 40.0)
    end = np.array([seeker['final_x'], seeker['final_y']])
    assert np.hypot(*(end - light)) < 0.15 < np.hypot(*(start - light))
    finder = headless_row('find_red_box.py', 'coloured_objects.yaml', 20.0)
    red = load_world(WORLDS / 'coloured_objects.yaml').boxes[0]
    assert np.hypot(finder['final_x'] - red.x, finder['final_y'] - red.y) < 0.2


def test_the_shim_camera_takes_the_size_of_the_images_it_is_given():
    """A simulation with a 104 x 78 camera, headless: the link says that size, and a Camera built with the e-puck's
    52 x 39 hands out the 104 x 78 images it samples (getWidth/getHeight, the BGRA buffer) as they are."""
    from types import SimpleNamespace

    from epuck_ros.model import CAMERA_FOV, CAMERA_HEIGHT, CAMERA_NEAR, CAMERA_WIDTH
    from epuck_ros.simulation import Simulation
    from epuck_ros.webots.devices import Camera as ShimCamera
    from epuck_ros.webots.headless import CoreLink
    sim = Simulation(load_world(WORLDS / 'coloured_objects.yaml'), noise=False)
    sim.senses.set_camera_size(104, 78)
    link = CoreLink(SimpleNamespace(sim=sim, recorder=lambda: None), 0)   # a stage without a bag
    link.want('camera')
    assert link.camera_size == (104, 78)
    camera = ShimCamera('camera', lambda: 0, CAMERA_WIDTH, CAMERA_HEIGHT, CAMERA_FOV, CAMERA_NEAR)
    camera.enable(32)
    image = sim.senses.readings_of(0)['camera']
    camera.sample(32_000_000, image)
    assert (camera.getWidth(), camera.getHeight(), len(camera.getImage())) == (104, 78, 104 * 78 * 4)
    assert camera.getImageArray()[103][77] == image[77, 103].tolist()
