"""Webots-style scripts in a headless trial (`webots.headless`), on the pure core, no DDS: each script's thread
takes the steps its answers complete, and the trial's loop takes over when a script ends or a step fails.
(Equality with the same runs over ROS: test_experiments.py.)"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from epuck_ros.experiments.trial import Script, Trial, run

FORWARD_THEN_RETURN = '''from controller import Robot
robot = Robot()
left, right = robot.getDevice('left wheel motor'), robot.getDevice('right wheel motor')
for motor in (left, right):
    motor.setPosition(float('inf'))
    motor.setVelocity(3.0)
steps = 10 if robot.getName() in ('epuck', 'epuck1') else 10**9
for _ in range(steps):
    if robot.step(32) == -1:
        break
'''


@pytest.fixture
def clean_imports():
    """The scripts' shim is put on sys.path and imported as `controller` in this process: taken off afterwards."""
    path_before, argv_before = list(sys.path), list(sys.argv)
    yield
    sys.path[:], sys.argv[:] = path_before, argv_before
    for module in [name for name in sys.modules if name == 'controller' or name.startswith('controller.')]:
        del sys.modules[module]


@pytest.mark.parametrize('robots', [0, 3])
def test_a_script_that_returns_early_leaves_its_wheels_still_to_the_end(tmp_path: Path, robots: int,
                                                                        clean_imports: None) -> None:
    """The script drives 10 steps, then returns: the run goes on to its end with that robot standing still (the
    others, with three robots, drive on), and no error."""
    script = tmp_path / 'short.py'
    script.write_text(FORWARD_THEN_RETURN)
    poses: list[np.ndarray] = []
    sim, _ = run(Trial(Script(str(script)), robots=robots, seed=1, duration=2.0, noise=False),
                 each_step=lambda sim: poses.append(sim.true_pose.copy()))
    track = np.array(poses)
    assert sim.time == pytest.approx(2.016) and len(track) == 63
    short = 1 if robots else 0   # epuck1 of three; the only robot of one
    assert np.linalg.norm(track[11, short, :2] - track[0, short, :2]) > 0.01   # it drove ...
    assert np.array_equal(track[12, short], track[-1, short])                # ... then stood still
    for other in set(range(len(sim.names))) - {short}:
        assert np.linalg.norm(track[-1, other, :2] - track[12, other, :2]) > 0.01


def test_a_step_failing_in_a_script_thread_is_the_trial_error(tmp_path: Path, clean_imports: None) -> None:
    """A single robot's steps are taken in its script's thread: an error there (a recorder's, say) ends the trial
    with that error, and the script sees step() == -1 (it does not get the error to catch)."""
    script = tmp_path / 'catches.py'
    script.write_text('from controller import Robot\nrobot = Robot()\nwhile True:\n    try:\n'
                      '        if robot.step(32) == -1:\n            break\n    except Exception:\n'
                      '        raise SystemExit(7)\n')

    def fail_at_step_five(sim: object) -> None:
        if sim.steps == 5:
            raise OSError('disk full')

    with pytest.raises(OSError, match='disk full'):
        run(Trial(Script(str(script)), duration=2.0), each_step=fail_at_step_five)


def test_copies_of_a_script_run_as_main_and_leave_this_process_main_alone(tmp_path: Path,
                                                                          clean_imports: None) -> None:
    """Each robot's copy runs as `python SCRIPT.py` would (`__name__ == '__main__'`), in a thread of this process,
    and this process's own __main__ stays what it was (a script left in its place made multiprocessing's spawned
    children, a local Dask cluster's workers, run that script)."""
    script = tmp_path / 'main_only.py'
    script.write_text("if __name__ == '__main__':\n" + ''.join(f'    {line}\n' for line in
                                                               FORWARD_THEN_RETURN.splitlines()))
    main_before = sys.modules['__main__']
    for _ in range(3):
        sim, _ = run(Trial(Script(str(script)), robots=3, seed=1, duration=0.5, noise=False))
        assert sys.modules['__main__'] is main_before
    assert sim.odom_pose[:, 0].all()   # every copy drove: each ran as __main__
