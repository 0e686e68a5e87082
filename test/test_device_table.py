"""The manual's device table (docs/senses.md), row by row: each device of Webots' e-puck in a reference situation,
Webots' figure (from its protos, its documented rules or its demos), ours computed here in the same situation, the
difference.

FIGURES is the one place the figures are stated; the table's rows quote it (the last test checks they do).
Where Webots and we differ the row says why, and the difference is asserted, not hidden in a tolerance.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from epuck_ros.model import CAMERA_POSE, LED_COLORS, SENSOR_POSES, TIME_STEP, RobotModel
from epuck_ros.simulation import Simulation
from epuck_ros.world import Box, World, world_from_dict
from epuck_ros.world.data import RobotStart

SENSES = Path(__file__).resolve().parents[1] / 'docs' / 'senses.md'


@dataclass(frozen=True)
class Figure:
    situation: str
    webots: str
    ours: str
    difference: str
    source: str


FIGURES = {
    'IR ps0..ps7': Figure(
        'ps0 facing a white smooth wall (red 1, roughness 0) 2 cm away across the floor, noise off',
        '379.99', '383.84', '+3.85 (+1.0 %)',
        "E-puckDistanceSensor.proto: the table (0.02 m: 383.84, 0.03 m: 234.93) and the ray tilted up 0.16 rad, so "
        "it meets the wall 2.026 cm away; ours runs level (ir_sensor.py)"),
    'ground gs0..gs2': Figure(
        'over white floor / over black paint, the floor of e-puck_line.wbt (roughness 0.2), noise off',
        '843.07 / 300', '843.07 / 300', '0 / 0',
        'E-puckGroundSensors.proto (3.3 mm up with E-puck.proto\'s slot, table [0: 1000, 0.016: 300]), '
        'WbDistanceSensor.cpp (f = 0.2 + 0.8 red (1 - 0.5 roughness)); e-puck_line_demo.c expects white > 800, '
        'line < 500'),
    'light ls0..ls7': Figure(
        'a point light (intensity 1, attenuation 0 0 1) 0.8 m along ls0\'s axis, noise off',
        '1791.56', '1791.56', '0',
        'lightsensor.md (E = I att (N.L)), E-puck.proto\'s table [1: 4095, 2: 0]'),
    'camera': Figure(
        'columns a red face 0.1 m wide covers 0.3 m straight ahead of the camera, 52 x 39, fov 0.84',
        '20', '20', '0',
        'E-puck.proto (52 x 39, fieldOfView 0.84 horizontal), camera.md (pinhole, square pixels)'),
    'accelerometer': Figure(
        'at rest', '0, 0, 9.81', '0, 0, 9.81', '0',
        'accelerometer.md (1 g along the vertical axis at rest), E-puck.proto\'s identity table'),
    'gyro': Figure(
        'spinning on the spot, wheels -0.5 / +0.5 of 6.28 rad/s (2.415 rad/s)', '0, 0, 18139.23',
        '0, 0, 18139.23', '0', "E-puck.proto's table [-13.315805: -100000, 13.315805: 100000]"),
    'encoders': Figure(
        'both wheels at 6.28 rad/s for 32 steps (1.024 s) from rest', '6.43072', '6.42770', '-0.00302 (-0.05 %)',
        "E-puck.proto's PositionSensor resolution 0.00628 (the proto's comment says 2 pi / 1000; we quantise "
        "to 2 pi / 1000)"),
    'ToF tof': Figure(
        'a wall 0.3 m ahead along its ray (e-puck2), noise off: getValue() / the `tof` Range', '323.23 / 0.3',
        '323.23 / 0.3', '0 / 0',
        'E-puck.proto version "2": DistanceSensor "tof", type "generic" (no reflection factor), one ray 2 m long, '
        'table (0.2 m: 218.9, 0.5 m: 531.9); webots_ros2 Ros2DistanceSensor.cpp and Math.cpp (the inverse table)'),
    'LEDs': Figure(
        'set(1) on led0, led8, led9: get() and the colour lit', '1: red, green, orange (1, 0.3, 0)',
        '1: red, green, orange (1, 0.3, 0)', '0',
        "E-puck.proto (led8 color 0 1 0, led9 color 1 0.3 0, the ring the LED node's default red)"),
}


def numbers(text: str) -> list[float]:
    return [float(n) for n in re.findall(r'-?\d+(?:\.\d+)?', text)]


def agrees(device: str, ours: list[float]) -> None:
    """Ours computed here is the table's `ours`, and differs from Webots' by the table's difference."""
    figure = FIGURES[device]
    stated = numbers(figure.ours)
    assert ours == pytest.approx(stated, abs=0.006), device
    if any(numbers(figure.difference)):
        assert stated[0] - numbers(figure.webots)[0] == pytest.approx(numbers(figure.difference)[0], abs=1e-6)
    else:
        assert figure.ours == figure.webots


def test_ir_wall_two_centimetres_ahead():
    yaw = -SENSOR_POSES[0, 2]   # ps0 looks along +x
    x = SENSOR_POSES[0, 0] * math.cos(yaw) - SENSOR_POSES[0, 1] * math.sin(yaw)
    world = World(arena_size=(2.0, 2.0), boxes=[Box(x + 0.02 + 0.05, 0.0, 0.1, 0.4)],
                  robots=[RobotStart('epuck', 0.0, 0.0, yaw)])
    sim = Simulation(world, noise=False)
    agrees('IR ps0..ps7', [float(sim.ir_raw[0, 0])])


def test_ground_over_white_and_over_black():
    world = world_from_dict({'arena': {'size': [1.0, 1.0]}, 'floor': {'paint': [
        {'polygon': [[0.2, -0.1], [0.4, -0.1], [0.4, 0.1], [0.2, 0.1]], 'color': [0, 0, 0]}]}})
    readings = []
    for x in (-0.3, 0.27):   # the sensors 3 cm ahead: on the white floor, on the black square
        sim = Simulation(world.with_robots([RobotStart('epuck', x, 0.0, 0.0)]), noise=False)
        sim.senses.want('ground', [0])
        readings.append(sim.senses.ground_raw[0])
    white, black = readings
    assert len(set(white.tolist())) == len(set(black.tolist())) == 1
    agrees('ground gs0..gs2', [float(white[0]), float(black[0])])


def test_light_point_light_along_ls0():
    from epuck_ros.model import LIGHT_SENSOR_HEIGHT
    from epuck_ros.sensors.light import LightSensors
    from epuck_ros.sensors.scene import Scene
    px, py, yaw = SENSOR_POSES[0]
    light = [px + 0.8 * math.cos(yaw), py + 0.8 * math.sin(yaw), LIGHT_SENSOR_HEIGHT]
    world = world_from_dict({'arena': {'size': [4.0, 4.0]}, 'lights': [{'position': light, 'intensity': 1.0}]})
    sensors = LightSensors(Scene(world, world.appearance))
    agrees('light ls0..ls7', [float(sensors.read(np.zeros((1, 3)), None)[0, 0])])


def test_camera_columns_of_a_face_ahead():
    from epuck_ros.sensors.camera import Camera
    from epuck_ros.sensors.scene import Scene
    world = world_from_dict({'arena': {'size': [2.0, 2.0]},
                             'boxes': [{'position': [CAMERA_POSE[0] + 0.3 + 0.05, 0.0], 'size': [0.1, 0.1],
                                        'color': [1, 0, 0]}]})
    image = Camera(Scene(world, world.appearance)).render(np.zeros((1, 3)))[0]
    red = (image[19, :, 0] == 255) & (image[19, :, 1] == 0)
    assert np.flatnonzero(red).tolist() == list(range(16, 36))
    agrees('camera', [float(red.sum())])


def test_accelerometer_at_rest_and_gyro_spinning():
    sim = Simulation(World(), noise=False)
    sim.senses.want('imu', [0])
    agrees('accelerometer', sim.senses.accelerometer[0].tolist())
    top = RobotModel().max_wheel_speed
    for _ in range(3):
        sim.command_wheels(0, -0.5 * top, 0.5 * top)
        sim.step()
    agrees('gyro', sim.senses.gyro[0].tolist())


def test_encoders_after_one_second_at_full_speed():
    sim = Simulation(World(), noise=False)
    top = RobotModel().max_wheel_speed
    for _ in range(32):
        sim.command_wheels(0, top, top)
        sim.step()
    assert sim.time == pytest.approx(32 * TIME_STEP)
    webots = round(top * 32 * TIME_STEP / 0.00628) * 0.00628   # Webots: the angle to the proto's resolution
    assert webots == pytest.approx(numbers(FIGURES['encoders'].webots)[0], abs=1e-12)
    agrees('encoders', sim.wheel_angles[0].tolist()[:1])
    assert sim.wheel_angles[0, 1] == sim.wheel_angles[0, 0]


def test_tof_wall_thirty_centimetres_ahead():
    from epuck_ros.model import TOF_POSE, TOF_LOOKUP_TABLE
    from epuck_ros.sensors.tof import range_from_value
    x, _, _, yaw = TOF_POSE
    world = World(arena_size=(2.0, 2.0), boxes=[Box(x + 0.3 * math.cos(yaw) + 0.05, 0.0, 0.1, 0.4)],
                  robots=[RobotStart('epuck', 0.0, 0.0, 0.0)])
    sim = Simulation(world, noise=False)
    sim.senses.want('tof', [0])
    webots = float(np.interp(0.3, TOF_LOOKUP_TABLE[:, 0], TOF_LOOKUP_TABLE[:, 1]))   # 218.9 + 313 / 3
    assert numbers(FIGURES['ToF tof'].webots) == pytest.approx([webots, 0.3], abs=0.006)
    agrees('ToF tof', [float(sim.senses.tof[0]), float(range_from_value(sim.senses.tof[0]))])


def test_leds_hold_their_value_and_light_in_their_colour():
    from epuck_ros.webots.devices import LED
    leds = [LED(f'led{i}') for i in (0, 8, 9)]
    for led in leds:
        led.set(1)
    assert [led.get() for led in leds] == [1, 1, 1]
    assert [LED_COLORS[i] for i in (0, 8, 9)] == [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 0.3, 0.0)]
    assert FIGURES['LEDs'].ours == FIGURES['LEDs'].webots


def test_the_manuals_table_quotes_these_figures():
    rows = {line.split('|')[1].strip(): line for line in SENSES.read_text().splitlines()
            if line.startswith('| ') and line.split('|')[1].strip() in FIGURES}
    assert sorted(rows) == sorted(FIGURES)
    for device, figure in FIGURES.items():
        cells = [cell.strip() for cell in rows[device].split('|')[1:-1]]
        assert cells[2:5] == [figure.webots, figure.ours, figure.difference], device
