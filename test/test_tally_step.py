"""A swarm's tally a step at a time (`RunTally.add_step`, NumPy over the robots) gives what `add`, robot by robot,
gives, to the bit: distances, contacts with walls, boxes, cylinders and other robots, stamps and final poses; and
`World.anything_within_each` answers as `anything_within` does."""
from __future__ import annotations

import numpy as np

from epuck_ros.bag.runs import RunData, Trajectory
from epuck_ros.bag.tally import CONTACT_MARGIN, RunTally, tally_runs
from epuck_ros.model import RobotModel
from epuck_ros.world import world_from_dict

WORLD = world_from_dict({'arena': {'size': [1.0, 1.0]},
                         'boxes': [{'position': [0.2, 0.1], 'size': [0.1, 0.2], 'yaw': 0.3}],
                         'cylinders': [{'position': [-0.2, -0.2], 'radius': 0.05}]})


def crowd(robots: int = 60, steps: int = 150) -> tuple[np.ndarray, np.ndarray]:
    """Random walks crowded into the arena (many contacts of every kind): (steps, robots, 2) and yaws."""
    rng = np.random.default_rng(1)
    walk = np.cumsum(rng.normal(0.0, 0.01, (steps, robots, 2)), axis=0) + rng.uniform(-0.5, 0.5, (1, robots, 2))
    return np.clip(walk, -0.49, 0.49), rng.uniform(-3.0, 3.0, (steps, robots))


def test_add_step_is_add_robot_by_robot():
    xy, yaw = crowd()
    names = [f'epuck{i}' for i in range(xy.shape[1])]
    one_by_one, by_step = RunTally(names, WORLD), RunTally(names, WORLD)
    for step, (points, yaws) in enumerate(zip(xy, yaw)):
        for name, (x, y), heading in zip(names, points.tolist(), yaws.tolist()):
            one_by_one.add(name, 32_000_000 * step, x, y, heading)
        by_step.add_step(32_000_000 * step, points[:, 0], points[:, 1], yaws)
    assert by_step.figures == one_by_one.figures
    assert by_step.contacts == one_by_one.contacts
    kinds = {contact.kind for contact in by_step.contacts}
    assert kinds == {'world', 'robot'} and by_step.robot_robot_contacts == one_by_one.robot_robot_contacts > 0
    assert by_step.figures[0].samples == len(xy) and by_step.figures[0].final_pose is not None


def test_tally_runs_feeds_whole_steps_and_the_stamps_some_robot_lacks():
    """A bag's runs: whole stamps go as steps, a stamp one robot lacks robot by robot; the same figures as `add`."""
    xy, yaw = crowd(robots=5, steps=40)
    stamps = np.arange(len(xy), dtype=np.int64) * 32_000_000
    runs = []
    for robot in range(xy.shape[1]):
        keep = np.ones(len(xy), dtype=bool) if robot else np.arange(len(xy)) != 7   # epuck0 lost step 7
        truth = Trajectory('ground_truth', stamps[keep] * 1e-9, xy[keep, robot, 0], xy[keep, robot, 1],
                           yaw[keep, robot], stamps[keep])
        runs.append(RunData(bag_path='', namespace=f'epuck{robot}', trajectory=truth, truth=truth, odom=None,
                            ranges=None, world=WORLD, closed_properly=True))
    expected = RunTally([run.name for run in runs], WORLD)
    for step in range(len(xy)):
        for run in runs:
            found = np.flatnonzero(run.truth.stamps_ns == stamps[step])
            if len(found):
                k = int(found[0])
                expected.add(run.name, int(stamps[step]), float(run.truth.x[k]), float(run.truth.y[k]),
                             float(run.truth.yaw[k]))
    tally = tally_runs(runs)
    assert tally.figures == expected.figures and tally.contacts == expected.contacts


def test_anything_within_each_is_anything_within():
    xy, _ = crowd()
    points = xy.reshape(-1, 2)
    reach = RobotModel().body_radius + CONTACT_MARGIN
    expected = [WORLD.anything_within(x, y, reach) for x, y in points.tolist()]
    assert WORLD.anything_within_each(points, reach).tolist() == expected and any(expected) and not all(expected)
