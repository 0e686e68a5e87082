"""What kind of run it was (`bag.shapes.classify`, in `bag summary` and bringup's summary) tells the truth: obstacle
avoidance, however it went, is never a rectangle, and the shipped bags of the true shapes keep their figures.

The avoidance bags are recorded here, headless (the same runs as over ROS, at the core's speed): the `avoid`
behaviour in a sweep, the course's obstacle_avoidance.py and the example avoid_obstacles.py through `webots_controller
--headless --record`; each was called a rectangle before (`Corners: 4: 110.7°, 87.7°, 70.0°, 58.9°`)."""
from __future__ import annotations

import math
import subprocess
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import BIN_DIR

from epuck_ros.bag.reader import Bag
from epuck_ros.bag.run_summary import load_runs, summarise_runs
from epuck_ros.bag.runs import Trajectory
from epuck_ros.bag.shapes import classify, classify_runs
from epuck_ros.world import default_world

REPO = Path(__file__).resolve().parents[1]
AVOID_OBSTACLES = REPO / 'epuck_ros' / 'webots' / 'examples' / 'avoid_obstacles.py'
COURSE_AVOIDANCE = REPO / 'test' / 'data' / 'course_controllers' / 'obstacle_avoidance.py'
COURSE_RECTANGLE = REPO / 'test' / 'data' / 'course_controllers' / 'controller_4.py'


def motions(bag: Path) -> list[str]:
    with Bag(bag) as reader:
        return [summary.motion for summary in summarise_runs(load_runs(reader)).robots]


def bag_summary(bag: Path) -> str:
    result = subprocess.run([str(BIN_DIR / 'bag'), 'summary', str(bag)], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return result.stdout


def test_a_sweeps_avoid_trials_are_free_motion(tmp_path):
    """The example sweep's avoid trials (both cruise speeds, one robot and three, seeds 0-3): nine of their 32 robots
    were called rectangles."""
    spec = tmp_path / 'avoid.yaml'
    controllers = ['avoid', {'behaviour': 'avoid', 'parameters': {'cruise_speed': 0.8}}]
    spec.write_text(yaml.safe_dump({'controllers': controllers, 'worlds': ['default'], 'robots': [1, 3],
                                    'seeds': {'first': 0, 'count': 4}, 'duration': 20, 'noise': True}))
    swept = subprocess.run([str(BIN_DIR / 'sweep'), str(spec), '-o', str(tmp_path / 'out'), '--record', '--workers',
                            '0'], capture_output=True, text=True, timeout=600)
    assert swept.returncode == 0, swept.stderr
    found = {bag.name: motions(bag) for bag in (tmp_path / 'out' / 'bags').iterdir()}
    assert len(found) == 16 and sum(len(robots) for robots in found.values()) == 32
    assert all(motion == 'free motion' for robots in found.values() for motion in robots), found
    assert 'Motion:            free motion' in bag_summary(tmp_path / 'out' / 'bags' / '0')


@pytest.mark.parametrize('script, seed, duration', [(AVOID_OBSTACLES, 0, 30), (AVOID_OBSTACLES, 3, 20),
                                                    (COURSE_AVOIDANCE, 0, 30)])
def test_obstacle_avoidance_scripts_are_free_motion(tmp_path, script, seed, duration):
    """The example avoid_obstacles.py (both were rectangles) and the course's obstacle avoidance, headless and
    recorded: free motion in bringup's summary (no corners) and in `bag summary`."""
    bag = tmp_path / 'bag'
    run = subprocess.run([str(BIN_DIR / 'webots_controller'), str(script), '--headless', '--seed', str(seed),
                          '--duration', str(duration), '--record', str(bag)], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert 'Corners' not in run.stdout, run.stdout
    assert 'Motion:            free motion' in bag_summary(bag)


@pytest.mark.parametrize('bag, motion, figures', [
    ('forward', 'straight line', 'Straight line:     0.2995 m heading 0.0°, max deviation 0.0000 m'),
    ('spin', 'spin in place', 'Heading rate:      -138.4°/s (-2.415 rad/s, clockwise), 1.53 turns'),
    ('circle', 'circle', 'Circle fit:        radius 0.0780 m, centre (0.000, 0.078), rms 0.0000 m, 1.04 laps'),
    ('rectangle', 'rectangle', 'Corners:           4: 89.8°, 90.0°, 90.0°, 88.9° (sides 0.313, 0.313, 0.313, 0.313 m)'),
    ('avoid', 'free motion', None)])
def test_the_shipped_bags_keep_their_shapes(bag, motion, figures):
    """bags/: what each run was and its figures, as `bag summary` said before."""
    text = bag_summary(REPO / 'bags' / bag)
    assert f'Motion:            {motion}' in text
    assert figures is None or figures in text, text


@pytest.mark.parametrize('controller', ['timed', 'sides', 'course'])
def test_rectangles_stay_rectangles(tmp_path, controller):
    """The rectangle behaviour's two turn modes (the course's 1 s turns: 82.4° corners; odometry: 90°) with sides of
    two lengths, and the course's controller_4.py: rectangles, their corners all alike."""
    bag = tmp_path / 'bag'
    if controller == 'course':
        command = ['webots_controller', str(COURSE_RECTANGLE), '--headless', '--duration', '30', '--record', str(bag)]
    else:
        parameters = {'turn_mode': 'timed'} if controller == 'timed' else {'side_a': 0.3, 'side_b': 0.15}
        spec = tmp_path / 'rectangle.yaml'
        spec.write_text(yaml.safe_dump({'controllers': [{'behaviour': 'rectangle', 'parameters': parameters}],
                                        'seeds': [0], 'duration': 30}))
        command = ['sweep', str(spec), '-o', str(tmp_path / 'out'), '--record', '--workers', '0']
        bag = tmp_path / 'out' / 'bags' / '0'
    run = subprocess.run([str(BIN_DIR / command[0]), *command[1:]], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert motions(bag) == ['rectangle']
    assert 'Corners:' in bag_summary(bag)


def square_path(x: float, y: float, side: float, laps: float = 1.25) -> Trajectory:
    """A square driven as the rectangle behaviour drives it: sides at 0.0628 m/s, turns in place of 90° left at
    1.45 rad/s, sampled every 32 ms from (x, y) heading along +x."""
    step, speed, rate = 0.032, 0.0628, 1.45
    xs, ys, yaws = [x], [y], [0.0]
    for corner in range(round(4 * laps)):
        for _ in range(round(side / speed / step)):
            xs.append(xs[-1] + speed * step * math.cos(yaws[-1]))
            ys.append(ys[-1] + speed * step * math.sin(yaws[-1]))
            yaws.append(yaws[-1])
        target = yaws[-1] + math.pi / 2
        while yaws[-1] < target - 1e-9:
            xs.append(xs[-1])
            ys.append(ys[-1])
            yaws.append(min(target, yaws[-1] + rate * step))
    stamps = np.arange(1, len(xs) + 1, dtype=np.int64) * 32_000_000
    return Trajectory('ground_truth', (stamps - stamps[0]) * 1e-9, np.array(xs), np.array(ys), np.array(yaws), stamps)


def test_corners_turned_where_the_sensors_see_a_wall_are_no_rectangles_corners():
    """The same square path in the open is a rectangle; driven along the arena's walls, each corner turned 0.06 m
    from a wall (where obstacle avoidance turns), it is free motion; without the world only the path is judged. Its
    five corners: at (0.15, -0.15) twice, (0.15, 0.15), (-0.15, 0.15), (-0.15, -0.15)."""
    arena = default_world()
    in_the_open = square_path(-0.15, -0.15, 0.3)
    along_the_walls = square_path(-0.44, -0.44, 0.88)
    assert classify_runs({'': in_the_open}, arena)[''].kind == 'rectangle'
    assert classify_runs({'': along_the_walls}, arena)[''].kind == 'free motion'
    assert classify(along_the_walls).kind == 'rectangle'
    # other robots' bodies count as walls do: standing next to most of the corners, not next to one

    def standing(x: float, y: float) -> Trajectory:
        count = len(in_the_open.t)
        return Trajectory('ground_truth', in_the_open.t, np.full(count, x), np.full(count, y), np.zeros(count),
                          in_the_open.stamps_ns)
    assert classify_runs({'a': in_the_open, 'b': standing(0.22, -0.15)}, arena)['a'].kind == 'rectangle'
    crowded = {'a': in_the_open, 'b': standing(0.22, -0.15), 'c': standing(0.22, 0.15)}
    assert classify_runs(crowded, arena)['a'].kind == 'free motion'
