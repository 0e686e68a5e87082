"""The world: default arena, YAML loading with named-field errors, hostile files, ray casting and collision push-out."""
import math
import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from epuck_ros.world import (MAX_FILE_BYTES, Box, Cylinder, RobotStart, World, WorldError, default_world, load_world,
                             world_from_dict, world_from_yaml)

WORLDS = Path(__file__).resolve().parent.parent / 'epuck_ros' / 'worlds'
RADIUS = 0.037


def cast(world: World, x: float, y: float, yaw: float, max_range: float = 10.0) -> float:
    return float(world.cast_rays(np.array([[x, y]]), np.array([yaw]), max_range)[0])


# --- the default world and the shipped files ------------------------------------------------------------

def test_default_world_file_equals_the_built_in_default():
    assert load_world(WORLDS / 'default.yaml') == default_world()


def test_default_world_is_the_course_arena_with_a_few_boxes_clear_of_the_start():
    world = default_world()
    assert world.arena_size == (1.0, 1.0)
    assert 3 <= len(world.boxes) <= 5
    assert all((box.size_x, box.size_y) == (0.1, 0.1) for box in world.boxes)
    x, y, _ = world.start_pose
    assert world.overlapping(x, y, RADIUS) == []
    # the 0.078 m circle either way around and the 0.31 m rectangle turning either way stay clear of the boxes
    for px, py in [(0.0, 0.156), (0.0, -0.156), (0.078, 0.078), (-0.078, 0.078), (0.314, 0.314), (0.314, -0.314)]:
        assert world.clearance(np.array([[px, py]]))[0] >= RADIUS


@pytest.mark.parametrize('name', ['default.yaml', 'corridor.yaml'])
def test_shipped_worlds_round_trip_through_to_dict(name):
    world = load_world(WORLDS / name)
    assert world_from_dict(world.to_dict()) == world
    assert world_from_dict(yaml.safe_load(yaml.safe_dump(world.to_dict()))) == world


def test_missing_fields_take_defaults():
    world = world_from_dict({'boxes': [{'position': [0.3, 0.3], 'size': [0.1, 0.2]}], 'robot': None})
    assert world.arena_size == (1.0, 1.0)
    assert world.boxes == (Box(0.3, 0.3, 0.1, 0.2, 0.0),)
    assert world.cylinders == ()
    assert world.start_pose == (0.0, 0.0, 0.0)


def test_empty_file_is_an_empty_arena(tmp_path):
    path = tmp_path / 'empty.yaml'
    path.write_text('')
    assert load_world(path) == World()


# --- world-file errors name the file, the field and the problem -------------------------------------------

@pytest.mark.parametrize('text, field, problem', [
    ('- 1\n- 2\n', '<top level>', 'expected a mapping'),
    ('obstacles: []\n', '<top level>', "unknown key 'obstacles'"),
    ('arena: {size: [1.0]}\n', 'arena.size', 'expected a list of 2 numbers'),
    ('arena: {size: [1.0, .nan]}\n', 'arena.size[1]', 'must be finite'),
    ('arena: {size: [0.0, 1.0]}\n', 'arena.size[0]', 'must be positive'),
    ('arena: [1, 1]\n', 'arena', 'expected a mapping'),
    ('boxes: {position: [0, 0]}\n', 'boxes', 'expected a list'),
    ('boxes:\n- {position: [0.3, 0.3], size: [0.1, 0.1]}\n- {position: [0.3, -0.3], size: [0.1, 0.1]}\n'
     '- {position: [-0.3, 0.3]}\n', 'boxes[2].size', 'missing'),
    ('boxes: [{size: [0.1, 0.1]}]\n', 'boxes[0].position', 'missing'),
    ('boxes: [{position: [0.3, 0.3], size: big}]\n', 'boxes[0].size', 'expected a list of 2 numbers'),
    ('boxes: [{position: [0.3, 0.3], size: [0.1, -0.2]}]\n', 'boxes[0].size[1]', 'must be positive'),
    ('boxes: [{position: [0.3, "a"], size: [0.1, 0.1]}]\n', 'boxes[0].position[1]', 'expected a number'),
    ('boxes: [{position: [0.3, 0.3], size: [0.1, 0.1], yaw: true}]\n', 'boxes[0].yaw', 'expected a number'),
    ('boxes: [{position: [0.3, 0.3], size: [0.1, 0.1], colour: red}]\n', 'boxes[0]', "unknown key 'colour'"),
    ('cylinders: [{position: [0.3, 0.3], radius: 0}]\n', 'cylinders[0].radius', 'must be positive'),
    ('cylinders: [{position: [0.3, 0.3]}]\n', 'cylinders[0].radius', 'missing'),
    ('robot: {start: [0, 0]}\n', 'robot.start', 'expected a list of 3 numbers'),
    ('robot: {start: [0, 0, .inf]}\n', 'robot.start[2]', 'must be finite'),
    ('robot: {start: [0.48, 0, 0]}\n', 'robot.start', 'not inside the 1.0 m x 1.0 m arena'),
    ('robot: {start: [2.0, 0, 0]}\n', 'robot.start', 'not inside'),
    ('boxes: [{position: [0.3, 0.3], size: [0.1, 0.1]}]\nrobot: {start: [0.3, 0.23, 0]}\n',
     'robot.start', 'overlaps boxes[0]'),
    ('cylinders: [{position: [0.1, 0], radius: 0.07}]\n', 'robot.start', 'overlaps cylinders[0]'),
    ('robot: {start: [0.463, 0, 0]}\n', 'robot.start', 'not inside'),                  # touching the wall
    ('robots: [{name: a, start: [0, 0, 0]}]\nrobot: {start: [0, 0, 0]}\n', 'robots', 'not both'),
    ('robots: []\n', 'robots', 'empty'),
    ('robots: {name: a}\n', 'robots', 'expected a list'),
    ('robots: [{name: a, start: [0, 0, 0]}, {name: a, start: [0.3, 0, 0]}]\n', 'robots', "both named 'a'"),
    ('robots: [{name: 3pi, start: [0, 0, 0]}]\n', 'robots[0].name', 'expected a ROS name'),
    ('robots: [{name: a/b, start: [0, 0, 0]}]\n', 'robots[0].name', 'expected a ROS name'),
    ('robots: [{name: a__b, start: [0, 0, 0]}]\n', 'robots[0].name', 'expected a ROS name'),
    ('robots: [{name: 7, start: [0, 0, 0]}]\n', 'robots[0].name', 'expected a ROS name'),
    ('robots: [{name: a}]\n', 'robots[0].start', 'missing'),
    ('robots: [{name: a, start: [0, 0, 0], colour: red}]\n', 'robots[0]', "unknown key 'colour'"),
    ('robots: [{name: a, start: [0, 0, 0]}, {name: b, start: [0.3, 0, 0]}, {name: c, start: [0.32, 0.06, 0]}]\n',
     'robots[2].start', "overlaps robots[1] ('b'"),
    ('robots: [{name: a, start: [0, 0, 0]}, {name: b, start: [0.074, 0, 0]}]\n', 'robots[1].start', 'overlaps'),
    ('robots: [{name: a, start: [0, 0.5, 0]}]\n', 'robots[0].start', 'not inside'),
    ('boxes: [{position: [0.3, 0.3], size: [0.1, 0.1]}]\nrobots: [{name: a, start: [0, 0, 0]}, '
     '{name: b, start: [0.3, 0.3, 0]}]\n', 'robots[1].start', 'overlaps boxes[0]'),
])
def test_bad_world_files_name_the_field(tmp_path, text, field, problem):
    path = tmp_path / 'bad.yaml'
    path.write_text(text)
    with pytest.raises(WorldError) as caught:
        load_world(path)
    message = str(caught.value)
    assert message.startswith(f'{path}: {field}: '), message
    assert problem in message


def test_a_robots_list_gives_named_robots_and_round_trips():
    world = world_from_yaml('robots:\n- {name: epuck0, start: [0.2, 0.1, 1.0]}\n- {name: scout, start: [-0.2, 0, 0]}\n')
    assert world.robots == (RobotStart('epuck0', 0.2, 0.1, 1.0), RobotStart('scout', -0.2, 0.0, 0.0))
    assert world.start_pose == (0.2, 0.1, 1.0)   # the first robot's, for one-robot callers
    assert world.to_dict()['robots'] == [{'name': 'epuck0', 'start': [0.2, 0.1, 1.0]},
                                         {'name': 'scout', 'start': [-0.2, 0.0, 0.0]}]
    assert 'robot' not in world.to_dict()
    assert world_from_dict(yaml.safe_load(yaml.safe_dump(world.to_dict()))) == world


def test_the_one_robot_form_is_one_robot_named_epuck_and_is_written_back_as_such():
    world = world_from_yaml('robot: {start: [0.1, 0.2, 0.3]}\n')
    assert world.robots == (RobotStart('epuck', 0.1, 0.2, 0.3),)
    assert world.to_dict()['robot'] == {'start': [0.1, 0.2, 0.3]} and 'robots' not in world.to_dict()
    assert World().names == ('epuck',)


def test_the_one_robot_constructor_form_still_works():
    assert World(start_pose=(0.1, 0.2, 0.3)) == World(robots=(RobotStart('epuck', 0.1, 0.2, 0.3),))
    with pytest.raises(WorldError, match='not both'):
        World(start_pose=(0, 0, 0), robots=(RobotStart('a', 0, 0),))


def test_a_world_built_in_code_checks_names():
    with pytest.raises(WorldError, match="robots: robots\\[1\\] and robots\\[0\\] are both named 'a'"):
        World(robots=(RobotStart('a', 0, 0), RobotStart('a', 0.3, 0)))
    with pytest.raises(WorldError, match='is not a ROS name'):
        World(robots=(RobotStart('no way', 0, 0),))


# --- hostile world files: one line naming the file and field, quickly, with little memory -------------------

def load_text(tmp_path, text: str) -> str:
    """The WorldError message for a file holding `text` (and that it came within a few seconds)."""
    path = tmp_path / 'hostile.yaml'
    path.write_text(text)
    begin = time.monotonic()
    with pytest.raises(WorldError) as caught:
        load_world(path)
    assert time.monotonic() - begin < 30.0   # generous; the point is "not minutes or hours"
    message = str(caught.value)
    assert message.startswith(f'{path}: ') and '\n' not in message and len(message) < 400, message
    return message[len(f'{path}: '):]


def test_yaml_aliases_are_refused_before_they_expand(tmp_path):
    # the "billion laughs": nine levels of nine aliases each expand to 9^9 (387 million) items
    lines = ['a0: &a0 [x, x, x, x, x, x, x, x, x]']
    lines += [f'a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']' for i in range(1, 10)]
    lines += ['boxes: *a9']
    assert load_text(tmp_path, '\n'.join(lines) + '\n').startswith('a1[0]: YAML aliases (*a0) are not allowed')
    assert load_text(tmp_path, 'robot: &r {start: [0, 0, 0]}\nrobots: [*r]\n').startswith('robots[0]: YAML aliases')


@pytest.mark.parametrize('text, field, problem', [
    ('arena: {size: [' + '9' * 400 + ', 1]}\n', 'arena.size[0]', 'must be within +-10000, got 9999999'),
    ('arena: {size: [1.0e+308, 1]}\n', 'arena.size[0]', 'must be within'),
    ('boxes: [{position: [-1.0e+308, 0], size: [0.1, 0.1]}]\n', 'boxes[0].position[0]', 'must be within'),
    ('robot: {start: [0, 0, 1.0e+300]}\n', 'robot.start[2]', 'must be within'),
    ('robots: [{name: a, start: [0, 0, .inf]}]\n', 'robots[0].start[2]', 'must be finite'),
    ('cylinders: [{position: [0.3, 0.3], radius: .nan}]\n', 'cylinders[0].radius', 'must be finite'),
    ('arena: {size: [1.0e+400, 1]}\n', 'arena.size[0]', 'must be finite'),
])
def test_huge_and_non_finite_numbers_name_the_field(tmp_path, text, field, problem):
    message = load_text(tmp_path, text)
    assert message.startswith(f'{field}: ') and problem in message, message


def test_deep_nesting_is_refused(tmp_path):
    assert 'nested deeper than' in load_text(tmp_path, 'boxes: ' + '[' * 5000 + ']' * 5000 + '\n')
    assert 'nested deeper than' in load_text(tmp_path, 'a: ' + '{a: ' * 5000 + '1' + '}' * 5000 + '\n')


def test_a_huge_value_is_not_formatted_into_the_message(tmp_path):
    message = load_text(tmp_path, 'boxes: [{position: [0, 0], size: "' + 'x' * 3_000_000 + '"}]\n')
    assert message.startswith('boxes[0].size: expected a list of 2 numbers, got str')


def test_a_named_pipe_is_refused_without_hanging(tmp_path):
    pipe = tmp_path / 'world.yaml'
    os.mkfifo(pipe)
    outcome = []

    def load() -> None:
        try:
            load_world(pipe)
        except WorldError as error:
            outcome.append(str(error))

    reader = threading.Thread(target=load, daemon=True)
    reader.start()
    reader.join(timeout=60.0)
    assert not reader.is_alive(), 'load_world blocked on a named pipe'
    assert outcome == [f'{pipe}: cannot read the file: not a regular file (a directory, pipe or device)']


def test_an_oversized_file_is_refused_unread(tmp_path):
    path = tmp_path / 'big.yaml'
    with open(path, 'wb') as file:
        file.truncate(50 * 2 ** 20)   # 50 MB, sparse: refused by its size before any byte is read
    expected = f'big.yaml: file too large \\({50 * 2 ** 20} bytes, at most {MAX_FILE_BYTES}\\)'
    with pytest.raises(WorldError, match=expected):
        load_world(path)
    with pytest.raises(WorldError, match='too large'):
        world_from_yaml('#' * (MAX_FILE_BYTES + 1), 'bag topic world')


def test_binary_and_unhashable_input_are_one_line(tmp_path):
    path = tmp_path / 'binary.yaml'
    path.write_bytes(bytes(range(256)))
    with pytest.raises(WorldError, match='binary.yaml: not UTF-8 text'):
        load_world(path)
    assert load_text(tmp_path, '{[1]: 2}\n').startswith('not valid YAML')
    assert load_text(tmp_path, 'a: ' + '1' * 5000 + '\n').startswith('not valid YAML')   # beyond int's digit limit


def test_missing_file_and_broken_yaml_are_world_errors(tmp_path):
    with pytest.raises(WorldError, match='nowhere.yaml: file not found'):
        load_world(tmp_path / 'nowhere.yaml')
    path = tmp_path / 'broken.yaml'
    path.write_text('arena: {size: [1, 1]\n')
    with pytest.raises(WorldError, match='broken.yaml: not valid YAML'):
        load_world(path)
    with pytest.raises(WorldError, match='cannot read'):
        load_world(tmp_path)


# --- ray casting -------------------------------------------------------------------------------------------

def test_rays_hit_the_arena_walls():
    world = World()
    assert cast(world, 0.0, 0.0, 0.0) == pytest.approx(0.5)
    assert cast(world, 0.2, 0.1, math.pi) == pytest.approx(0.7)
    assert cast(world, 0.2, 0.1, -math.pi / 2) == pytest.approx(0.6)
    assert cast(world, 0.0, 0.0, math.pi / 4) == pytest.approx(0.5 * math.sqrt(2))
    assert cast(world, 0.0, 0.0, 0.3) == pytest.approx(0.5 / math.cos(0.3))


def test_rays_beyond_max_range_are_inf():
    world = World()
    assert cast(world, 0.44, 0.0, 0.0, max_range=0.07) == pytest.approx(0.06)
    assert cast(world, 0.42, 0.0, 0.0, max_range=0.07) == math.inf


def test_rays_hit_the_nearest_face_of_a_box_even_rotated():
    world = World(boxes=[Box(0.3, 0.0, 0.1, 0.2), Box(-0.3, 0.0, 0.1, 0.1, math.pi / 4)])
    assert cast(world, 0.0, 0.0, 0.0) == pytest.approx(0.25)
    assert cast(world, 0.0, 0.05, 0.0) == pytest.approx(0.25)
    assert cast(world, 0.0, 0.15, 0.0) == pytest.approx(0.5)   # passes above the box
    assert cast(world, 0.0, 0.0, math.pi) == pytest.approx(0.3 - 0.05 * math.sqrt(2))  # the diamond's corner


def test_rays_hit_cylinders():
    world = World(cylinders=[Cylinder(0.3, 0.0, 0.05)])
    assert cast(world, 0.0, 0.0, 0.0) == pytest.approx(0.25)
    assert cast(world, 0.0, 0.03, 0.0) == pytest.approx(0.3 - math.sqrt(0.05 ** 2 - 0.03 ** 2))
    assert cast(world, 0.0, 0.06, 0.0) == pytest.approx(0.5)   # misses it
    assert cast(world, 0.0, 0.0, math.pi) == pytest.approx(0.5)  # it is behind


def test_many_rays_in_one_call():
    world = default_world()
    yaws = np.linspace(-math.pi, math.pi, 64, endpoint=False)
    origins = np.tile([0.1, -0.2], (64, 1))
    distances = world.cast_rays(origins, yaws, 2.0)
    assert distances.shape == (64,)
    assert np.all(np.isfinite(distances))
    assert distances == pytest.approx([cast(world, 0.1, -0.2, yaw, 2.0) for yaw in yaws])


# --- collisions --------------------------------------------------------------------------------------------

@pytest.mark.parametrize('world, inside, expected', [
    (World(), (0.48, 0.1), (0.5 - RADIUS, 0.1)),                                  # a wall
    (World(), (-0.49, -0.47), (-0.5 + RADIUS, -0.5 + RADIUS)),                    # a corner of the arena
    (World(boxes=[Box(0.2, 0.0, 0.1, 0.1)]), (0.12, 0.01), (0.15 - RADIUS, 0.01)),  # a box face
    (World(boxes=[Box(0.2, 0.0, 0.1, 0.1, math.pi / 2)]), (0.2, -0.07), (0.2, -0.05 - RADIUS)),
    (World(cylinders=[Cylinder(0.0, 0.2, 0.03)]), (0.0, 0.14), (0.0, 0.2 - 0.03 - RADIUS)),
])
def test_a_penetrating_disc_is_pushed_out_to_touch(world, inside, expected):
    xy, contact = world.resolve_collision(np.array([inside]), RADIUS)
    assert xy[0] == pytest.approx(expected, abs=1e-12)
    assert contact[0]
    assert world.clearance(xy)[0] == pytest.approx(RADIUS)


def test_a_disc_at_a_box_corner_is_pushed_diagonally():
    world = World(boxes=[Box(0.0, 0.0, 0.1, 0.1)])
    xy, contact = world.resolve_collision(np.array([[0.07, 0.07]]), RADIUS)
    assert contact[0]
    assert xy[0] == pytest.approx([0.05 + RADIUS / math.sqrt(2)] * 2)


def test_a_disc_clear_of_everything_is_untouched():
    world = default_world()
    xy, contact = world.resolve_collision(np.array([[0.0, 0.0], [0.2, 0.3]]), RADIUS)
    np.testing.assert_array_equal(xy, [[0.0, 0.0], [0.2, 0.3]])
    assert not contact.any()


def test_a_disc_in_a_gap_narrower_than_itself_goes_back_to_where_it_was_clear():
    world = World(boxes=[Box(0.0, 0.0, 0.1, 0.1), Box(0.0, 0.11, 0.1, 0.1)])   # 1 cm gap at y = 0.055
    xy, contact = world.resolve_collision(np.array([[0.04, 0.055]]), RADIUS, previous=np.array([[0.1, 0.055]]))
    assert contact[0]
    np.testing.assert_array_equal(xy, [[0.1, 0.055]])


@pytest.mark.parametrize('world', [
    default_world(),
    World(arena_size=(1.2, 0.8), boxes=[Box(0.2, 0.1, 0.1, 0.2, 0.3), Box(-0.3, -0.2, 0.05, 0.3, -1.0)],
          cylinders=[Cylinder(0.0, 0.25, 0.05), Cylinder(-0.1, -0.1, 0.02)]),
    World(arena_size=(4.0, 4.0),   # enough obstacles that each disc is tested only against its grid cell's
          boxes=[Box(x, y, 0.08, 0.15, x + y) for x in np.linspace(-1.7, 1.7, 7) for y in (-1.0, 0.2, 1.4)],
          cylinders=[Cylinder(x, y, 0.04) for x in np.linspace(-1.5, 1.5, 6) for y in (-0.4, 0.8)]),
])
def test_many_discs_at_once_move_exactly_like_one_at_a_time(world):
    """resolve_collision (NumPy, many robots) and push_disc_out (floats, one robot) follow the same rule."""
    rng = np.random.default_rng(0)
    half = np.array(world.arena_size) / 2
    clear = rng.uniform(-half, half, (6000, 2))
    clear = clear[world.clearance(clear) > RADIUS]            # where robots were, clear of everything
    step = rng.uniform(0.0, RADIUS / 2, len(clear))           # at most half a radius per substep
    angle = rng.uniform(-math.pi, math.pi, len(clear))
    moved = clear + step[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
    xy, touching = world.resolve_collision(moved, RADIUS, clear)
    one_by_one = [world.push_disc_out(x, y, RADIUS, (px, py)) for (x, y), (px, py) in zip(moved, clear)]
    np.testing.assert_allclose(xy, [(x, y) for x, y, _ in one_by_one], atol=1e-12)
    assert touching.tolist() == [t for _, _, t in one_by_one]
    assert 0 < touching.sum() < len(clear)


def test_many_rays_at_once_see_what_one_ray_sees_in_a_crowded_world():
    world = World(arena_size=(4.0, 4.0),
                  boxes=[Box(x, y, 0.08, 0.15, x + y) for x in np.linspace(-1.7, 1.7, 7) for y in (-1.0, 0.2, 1.4)],
                  cylinders=[Cylinder(x, y, 0.04) for x in np.linspace(-1.5, 1.5, 6) for y in (-0.4, 0.8)])
    rng = np.random.default_rng(1)
    origins = rng.uniform(-1.9, 1.9, (3000, 2))
    origins = origins[world.clearance(origins) > 0.0]
    yaws = rng.uniform(-math.pi, math.pi, len(origins))
    together = world.cast_rays(origins, yaws, 0.3)             # the grid path
    one_by_one = [cast(world, x, y, yaw, 0.3) for (x, y), yaw in zip(origins, yaws)]   # every obstacle
    np.testing.assert_allclose(together, one_by_one, atol=1e-12)
    assert 0 < np.isfinite(together).sum() < len(origins)


@pytest.mark.parametrize('world', [
    default_world(),
    World(arena_size=(1.2, 0.8), boxes=[Box(0.2, 0.1, 0.1, 0.2, 0.3), Box(-0.3, -0.2, 0.05, 0.3, -1.0)],
          cylinders=[Cylinder(0.0, 0.25, 0.05), Cylinder(-0.1, -0.1, 0.02)]),
    World(arena_size=(4.0, 4.0),   # so many obstacles that the rays go to ray_distances' grid
          boxes=[Box(x, y, 0.08, 0.15, x + y) for x in np.linspace(-1.7, 1.7, 7) for y in np.linspace(-1.6, 1.6, 5)],
          cylinders=[Cylinder(x, y, 0.04) for x in np.linspace(-1.5, 1.5, 6) for y in (-0.4, 0.8)]),
])
def test_one_robots_rays_on_floats_equal_the_numpy_rays_to_the_bit(world):
    """cast_near (plain floats, the surfaces near one robot) gives exactly ray_distances' values, parallel rays too."""
    rng = np.random.default_rng(2)
    half = np.array(world.arena_size) / 2
    centres = rng.uniform(-half, half, (1500, 2))
    centres = centres[world.clearance(centres) > RADIUS]
    reach, max_range, hits = 0.11, 0.07, 0
    for x, y in centres.tolist():
        angles = rng.uniform(-math.pi, math.pi, 8)
        angles[:2] = 0.0, math.pi / 2   # along the walls' edges
        offsets = rng.uniform(-0.03, 0.03, (8, 2))
        ox, oy, dx, dy = x + offsets[:, 0], y + offsets[:, 1], np.cos(angles), np.sin(angles)
        expected = world.ray_distances(ox, oy, dx, dy, max_range)
        surfaces = world.surfaces_near(x, y, reach)
        found = world.cast_near(surfaces, list(zip(ox.tolist(), oy.tolist(), dx.tolist(), dy.tolist())), max_range)
        assert found == expected.tolist() or not surfaces and np.isinf(expected).all()
        hits += int(np.isfinite(expected).sum())
    assert hits > 100


def test_clearance_is_the_distance_to_the_nearest_surface():
    world = World(boxes=[Box(0.2, 0.0, 0.1, 0.1)], cylinders=[Cylinder(-0.2, 0.0, 0.05)])
    points = np.array([[0.0, 0.0], [0.0, 0.45], [0.2, 0.0], [-0.12, 0.0]])
    np.testing.assert_allclose(world.clearance(points), [0.15, 0.05, 0.0, 0.03])


@pytest.mark.parametrize('text, field', [
    ('boxes: [{position: [0.8, 0], size: [0.1, 0.1]}]\n', 'boxes[0].position'),
    ('boxes: [{position: [0, 0.2], size: [0.1, 0.1]}, {position: [0.47, 0], size: [0.1, 0.1], yaw: 0.5}]\n',
     'boxes[1].position'),
    ('cylinders: [{position: [-0.48, 0.3], radius: 0.03}]\n', 'cylinders[0].position'),
])
def test_an_obstacle_outside_the_arena_is_refused_naming_it(tmp_path, text, field):
    """A box at x = 0.8 m in a 1 m arena was accepted and silently left out of every picture and sensor."""
    message = load_text(tmp_path, text)
    assert message.startswith(f'{field}: ') and 'does not lie whole inside the 1.0 m x 1.0 m arena' in message


def test_an_obstacle_touching_a_wall_is_fine(tmp_path):
    path = tmp_path / 'flush.yaml'
    path.write_text('boxes: [{position: [0.45, 0], size: [0.1, 0.1]}]\ncylinders: [{position: [0, -0.46], '
                    'radius: 0.04}]\nrobot: {start: [-0.2, 0.2, 0]}\n')
    assert len(load_world(path).boxes) == 1


def test_every_shipped_world_loads():
    worlds = sorted((Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds').glob('*.yaml'))
    assert worlds and all(load_world(path) for path in worlds)


def test_a_name_too_long_for_a_topic_is_refused_at_load(tmp_path):
    """A valid 240-character name made the simulator die with InvalidTopicNameException once prefixed."""
    message = load_text(tmp_path, f'robots: [{{name: {"a" * 240}, start: [0, 0, 0]}}]\n')
    assert message.startswith('robots[0].name: at most 100 characters') and 'got 240' in message
