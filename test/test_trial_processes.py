"""A script trial's processes (issue 28): none outlives its trial, whatever the script did (a child left running,
a fork that calls setsid); a trial that kills its Dask worker is its own error row; a trial over its memory limit
is killed and its row says so; `webots_controller --headless` keeps no per-step samples beyond a bound."""
from __future__ import annotations

import csv
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from conftest import BIN_DIR

from epuck_ros.experiments.spec import load_spec
from epuck_ros.experiments.trial import run_trial

SWEEP = str(BIN_DIR / 'sweep')
LEAVES_A_CHILD = '''import os, subprocess, sys
from controller import Robot
here = os.path.dirname(os.path.abspath(__file__))
child = subprocess.Popen(['sleep', '1234'])
open(os.path.join(here, 'leaves_a_child.pid'), 'w').write(str(child.pid))
robot = Robot()
while robot.step(32) != -1:
    pass
'''
DAEMON = '''import os, time
from controller import Robot
here = os.path.dirname(os.path.abspath(__file__))
robot = Robot()
written, told = os.pipe()
if os.fork() == 0:   # a daemon as the books make one: fork, setsid, fork, and the middle one ends
    os.setsid()
    if os.fork() == 0:
        open(os.path.join(here, 'daemon.pid'), 'w').write(str(os.getpid()))
        os.write(told, b'1')   # its pid is on disk before the script steps (the trial may end at once after)
        time.sleep(1234)
    os._exit(0)
os.read(written, 1)
while robot.step(32) != -1:
    pass
'''
KILLS_ITS_WORKER = '''import os, signal
from controller import Robot
robot = Robot()
robot.step(32)
with open(f'/proc/{os.getppid()}/stat') as stat:   # the trial's keeper; its parent is the Dask worker
    worker = int(stat.read().rpartition(')')[2].split()[1])
os.kill(worker, signal.SIGKILL)
while robot.step(32) != -1:
    pass
'''
HOGS = '''import os, subprocess, sys, time
from controller import Robot
robot = Robot()
if sys.argv[0].endswith('hogs_in_a_child.py'):
    subprocess.Popen([sys.executable, '-c', 'x = bytearray(1_500_000_000)\\nfor i in range(0, len(x), 4096): '
                      'x[i] = 1\\nimport time; time.sleep(600)'])
else:
    x = bytearray(1_500_000_000)
    for i in range(0, len(x), 4096):
        x[i] = 1
while robot.step(32) != -1:
    time.sleep(0.01)
'''


def alive(pid: int) -> bool:
    """Whether `pid` is a living process (not ended, not a zombie)."""
    try:
        state = Path(f'/proc/{pid}/stat').read_text().rpartition(')')[2].split()[0]
    except OSError:
        return False
    return state != 'Z'


def test_a_script_trial_leaves_no_process_behind(tmp_path):
    """Item 14: a script that starts `sleep 1234` left it running after the sweep; one that made itself a daemon
    (fork, setsid, fork) left a copy of the sweep alive and its trial reported over its time limit. Both trials now
    end as the script's run ends, with every process they started."""
    (tmp_path / 'leaves_a_child.py').write_text(LEAVES_A_CHILD)
    (tmp_path / 'daemon.py').write_text(DAEMON)
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [{script: leaves_a_child.py}, {script: daemon.py}]\nseeds: [0]\nduration: 1\n'
                    'time_limit: 30\n')
    for trial in load_spec(spec).trials:
        rows = run_trial(trial)
        assert [row['error'] for row in rows] == [''], rows
    pids = [int((tmp_path / name).read_text()) for name in ('leaves_a_child.pid', 'daemon.pid')]
    assert not any(alive(pid) for pid in pids)


def test_a_trial_that_kills_its_dask_worker_is_its_error_row_and_the_sweep_goes_on(tmp_path):
    """Item 15: a KilledWorker traceback, exit 1 and no summary; now that trial's row and the others ran."""
    (tmp_path / 'kills_its_worker.py').write_text(KILLS_ITS_WORKER)
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [{script: kills_its_worker.py}, avoid]\nseeds: [0]\nduration: 1\n')
    result = subprocess.run([SWEEP, str(spec), '-o', str(tmp_path / 'out'), '--workers', '1'], capture_output=True,
                            text=True, timeout=300)
    assert result.returncode == 1 and 'Traceback' not in result.stderr, result.stderr
    assert '1 trials failed (their rows say why)' in result.stderr and '±' in result.stdout
    with open(tmp_path / 'out' / 'trials.csv', newline='') as table:
        rows = {row['controller']: row for row in csv.DictReader(table)}
    assert rows['kills_its_worker.py']['error'].startswith('its Dask worker died each time Dask ran the trial, '
                                                           'alone on the cluster too (KilledWorker)')
    assert rows['avoid']['error'] == '' and float(rows['avoid']['distance_m']) > 0


@pytest.mark.parametrize('script', ['hogs.py', 'hogs_in_a_child.py'])
def test_a_trial_over_its_memory_limit_is_killed_and_its_row_says_so(tmp_path, script):
    """Item 18: a script trial reached 6.3 GB with no error row. Here it takes 1.5 GB, itself or in a process it
    starts, against a limit of 200 MB: killed, its row saying the limit, nothing left running."""
    (tmp_path / script).write_text(HOGS)
    spec = tmp_path / 'spec.yaml'
    spec.write_text(f'controllers: [{{script: {script}}}]\nseeds: [0]\nduration: 60\nmemory_limit: 200\n')
    (trial,) = load_spec(spec).trials
    (row,) = run_trial(trial)
    assert row['error'].endswith("more than 200 (the memory limit): the trial's processes were killed"), row


@pytest.fixture
def clean_imports() -> Iterator[None]:
    """A script's shim sits on sys.path while it runs, as for a library user: taken off again afterwards."""
    path = list(sys.path)
    yield
    sys.path[:] = path
    for module in [name for name in sys.modules if name == 'controller' or name.startswith('controller.')]:
        del sys.modules[module]


def test_webots_controller_headless_keeps_no_samples_beyond_its_bound(monkeypatch, capsys, clean_imports):
    """Item 18: `--headless` kept ~184 bytes per robot-step (1,000 robots for an hour: ~20 GB) for the shapes in
    its summary. Now 32 bytes per robot-step in arrays made once, and none beyond MAX_SHAPE_SAMPLES: the summary
    then has distance and contacts without the shapes, and says so."""
    from epuck_ros.experiments import headless_cli
    small = headless_cli.Tracks(3, 30.0)
    assert small.kept and small.poses.nbytes == 3 * 24 * len(small.stamps) and len(small.stamps) < 30 / 0.032 + 3
    huge = headless_cli.Tracks(1000, 3600.0)
    assert not huge.kept and huge.poses.nbytes + huge.stamps.nbytes == 0
    script = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples' / 'avoid_obstacles.py'
    common = [str(script), '--duration', '2', '--robots', '3']
    headless_cli.main(common)
    shapes = capsys.readouterr().out
    monkeypatch.setattr(headless_cli, 'MAX_SHAPE_SAMPLES', 10)
    headless_cli.main(common)
    summed = capsys.readouterr().out
    distances = [line for line in shapes.splitlines() if ' m in ' in line]
    assert len(distances) == 3 and distances == [line for line in summed.splitlines() if ' m in ' in line]
    shape_line = '[webots_controller]   '   # a shape's figures, under its robot's line
    assert shape_line in shapes and 'shapes not classified' not in shapes
    assert shape_line not in summed and 'shapes not classified: 3 robots x 63 steps, more than the 10 samples' in summed
