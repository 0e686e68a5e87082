"""`sweep` under hostile or careless use (issue 28): honest exit codes, resumes that refuse what is not theirs,
one sweep per folder, a scheduler checked before the folder is touched, scripts that are no files, and one line,
never a traceback, for every bad input."""
from __future__ import annotations

import csv
import os
import shutil
import signal
import socket
import subprocess
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import BIN_DIR

SWEEP, EVOLVE, CONTROLLER = (str(BIN_DIR / name) for name in ('sweep', 'evolve', 'webots_controller'))
EXAMPLE_SCRIPT = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'webots' / 'examples' / 'avoid_obstacles.py'
WAITS = '''import os, time
from controller import Robot
here = os.path.dirname(os.path.abspath(__file__))
robot = Robot()
open(os.path.join(here, 'started'), 'w').close()
while os.path.exists(os.path.join(here, 'hold')):
    time.sleep(0.01)
while robot.step(32) != -1:
    pass
'''
"""A script whose trial waits, before its first step, for as long as the file `hold` beside it exists."""
RAISES = 'from controller import Robot\nrobot = Robot()\nrobot.step(32)\n1 / 0\n'


def sweep(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([SWEEP, *args], capture_output=True, text=True, timeout=timeout)


def rows_of(table: Path) -> list[dict]:
    """The rows without their wall time (the only column that depends on the machine)."""
    with open(table, newline='') as stream:
        return [{key: value for key, value in row.items() if key != 'wall_s'} for row in csv.DictReader(stream)]


def one_line(result: subprocess.CompletedProcess, code: int = 2) -> str:
    """The one line a refused command printed (asserting it printed one line and no traceback)."""
    assert result.returncode == code, result.stdout + result.stderr
    assert 'Traceback' not in result.stderr and result.stderr.count('\n') == 1, result.stderr
    return result.stderr


def wait_for(condition: Callable[[], bool], process: subprocess.Popen) -> None:
    """Until `condition()` holds (a state the test waits for, not a time), failing if the process ended first."""
    deadline = time.monotonic() + 120
    while not condition():
        assert process.poll() is None, process.communicate()
        assert time.monotonic() < deadline, 'the state waited for never came'
        time.sleep(0.02)


def holding_spec(tmp_path: Path) -> Path:
    """Two avoid trials, then two trials of WAITS, which wait while tmp_path/hold exists (it does)."""
    (tmp_path / 'waits.py').write_text(WAITS)
    (tmp_path / 'hold').touch()
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [avoid, {script: waits.py}]\nseeds: [0, 1]\nduration: 2\n')
    return spec


@pytest.mark.parametrize('number, code', [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_an_interrupted_sweep_exits_as_shells_expect_and_resume_runs_the_rest(tmp_path, number, code):
    """Issue 28, item 1: 130 after Ctrl-C, 143 after SIGTERM (was 0, and SIGTERM lost the summary); the trials
    done are kept and `--resume` runs the others, to the same rows as a sweep never interrupted."""
    spec, out = holding_spec(tmp_path), tmp_path / 'out'
    process = subprocess.Popen([SWEEP, str(spec), '-o', str(out), '--workers', '0'], stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    wait_for(lambda: (tmp_path / 'started').exists(), process)   # the two avoid trials are written
    process.send_signal(number)
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == code, stderr
    assert 'interrupted with 2 of 4 trials done' in stderr and 'Traceback' not in stderr and '±' in stdout
    assert [row['trial'] for row in rows_of(out / 'trials.csv')] == ['0', '1']
    (tmp_path / 'hold').unlink()
    resumed = sweep(str(spec), '-o', str(out), '--workers', '0', '--resume')
    assert resumed.returncode == 0 and '4 trials (2 done before)' in resumed.stderr, resumed.stderr
    whole = sweep(str(spec), '-o', str(tmp_path / 'whole'), '--workers', '0')
    assert whole.returncode == 0, whole.stderr
    assert rows_of(out / 'trials.csv') == rows_of(tmp_path / 'whole' / 'trials.csv')


def test_a_failed_trials_rows_keep_its_robots(tmp_path):
    """Item 2: a row per robot, each with the trial's robot count and the robot's name (was one row, robots 0)."""
    (tmp_path / 'raises.py').write_text(RAISES)
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [{script: raises.py}]\nrobots: [1, 3]\nseeds: [5]\nduration: 1\n')
    result = sweep(str(spec), '-o', str(tmp_path / 'out'), '--workers', '0')
    assert result.returncode == 1, result.stderr
    rows = rows_of(tmp_path / 'out' / 'trials.csv')
    assert [(row['trial'], row['robots'], row['seed'], row['robot']) for row in rows] == \
        [('0', '1', '5', 'epuck'), ('1', '3', '5', 'epuck0'), ('1', '3', '5', 'epuck1'), ('1', '3', '5', 'epuck2')]
    assert all(row['error'].startswith('ScriptError: raises.py: ZeroDivisionError') for row in rows)


def test_scripts_and_worlds_are_named_by_their_own_names_unique_in_the_sweep(tmp_path):
    """Item 5: the table and the picture name a script by its file's name, with as many folders as make it
    unique (was a path cut from the left, '…ples/avoid_obstacles.py', or the spec's '../../…')."""
    for folder in ('a', 'b', 'shared'):
        (tmp_path / folder).mkdir()
    for script in ('a/ctl.py', 'b/ctl.py', 'shared/avoid_obstacles.py'):
        (tmp_path / script).write_text(EXAMPLE_SCRIPT.read_text())
    (tmp_path / 'shared' / 'arena.yaml').write_text('arena: {size: [1.2, 1.2]}\n')
    (tmp_path / 'specs').mkdir()
    spec = tmp_path / 'specs' / 'spec.yaml'
    spec.write_text('controllers: [{script: ../a/ctl.py}, {script: ../b/ctl.py}, '
                    '{script: ../shared/avoid_obstacles.py}]\nworlds: [default, ../shared/arena.yaml]\n'
                    'seeds: [0]\nduration: 1\n')
    result = sweep(str(spec), '-o', str(tmp_path / 'out'), '--workers', '0')
    assert result.returncode == 0, result.stderr
    rows = rows_of(tmp_path / 'out' / 'trials.csv')
    assert {row['controller'] for row in rows} == {'a/ctl.py', 'b/ctl.py', 'avoid_obstacles.py'}
    assert {row['world'] for row in rows} == {'default', 'arena.yaml'}
    assert all(name in result.stdout for name in ('a/ctl.py', 'b/ctl.py', 'avoid_obstacles.py', 'arena.yaml'))
    assert '…' not in result.stdout and '..' not in result.stdout


def test_the_eta_comes_from_the_trials_done_not_from_the_start_up():
    """Item 5: the first ETA said 61 s for a 12 s job (the cluster's start-up counted as trials' time): now the
    mean wall time of the trials done, times the trials left, over the trials that run at once."""
    from epuck_ros.experiments.cli import Progress
    clock = iter([60.0, 61.0, 62.0]).__next__   # a minute of start-up before the first trial ended
    progress = Progress(12, 2, clock)
    progress.show([{'error': '', 'wall_s': '1.0'}])
    assert progress.line().startswith('[sweep] 1/12 trials, 0 failed, ETA 6 s')   # 1 s x 11 / 2
    progress.show([{'error': 'x', 'wall_s': '3.0'}, {'error': 'x', 'wall_s': '3.0'}])
    assert progress.line().startswith('[sweep] 2/12 trials, 1 failed, ETA 10 s')   # 2 s x 10 / 2


RESUMABLE = 'controllers: [avoid]\nrobots: [1, 3]\nseeds: {first: 0, count: 3}\nduration: 2\n'


@pytest.fixture(scope='module')
def finished_table(tmp_path_factory: pytest.TempPathFactory) -> str:
    """The table of a finished sweep of RESUMABLE (6 trials, 1 and 3 robots, 3 seeds)."""
    folder = tmp_path_factory.mktemp('resumable')
    (folder / 'spec.yaml').write_text(RESUMABLE)
    assert sweep(str(folder / 'spec.yaml'), '-o', str(folder / 'out'), '--workers', '0').returncode == 0
    return (folder / 'out' / 'trials.csv').read_text()


def resume_case(tmp_path: Path, table: str) -> tuple[Path, Path]:
    """An output folder holding `table`, and the spec RESUMABLE beside it."""
    spec, out = tmp_path / 'spec.yaml', tmp_path / 'out'
    spec.write_text(RESUMABLE)
    out.mkdir()
    (out / 'trials.csv').write_text(table)
    return spec, out


@pytest.mark.parametrize('change, problem', [
    (lambda spec, table: (spec.replace('count: 3', 'count: 4'), table), 'line 5: trial 3 there is not trial 3 of'),
    (lambda spec, table: (spec.replace('[avoid]', '[spin]'), table), 'line 2: trial 0 there is not trial 0 of'),
    (lambda spec, table: (spec, table.replace('\n1,avoid', '\n-7,avoid')), "line 3: trial '-7': not a trial"),
    (lambda spec, table: (spec, table.replace('\n1,avoid', '\ntwo,avoid')), "line 3: trial 'two': not a trial"),
    (lambda spec, table: (spec, table.replace(',0.0,0.0,2.016,', ',0.0,lots,2.016,', 1)),
     "line 2: final_yaw 'lots': not a number"),
    (lambda spec, table: (spec, 'a,b,c\n1,2,3\n'), 'not the table of a sweep of this version'),
])
def test_resume_refuses_a_table_that_is_not_this_sweeps_with_one_line(tmp_path, finished_table, change, problem):
    """Item 9: an edited spec (seed count 3 -> 4: was 15 runs for 12), another spec (was: nothing run, the old rows
    shown), trial -7 (was kept), trial 'two', a word for a number, a foreign header (were tracebacks, the last after
    running every trial): one line naming the file and line, exit 2, before any trial, the table left as it was."""
    spec, out = resume_case(tmp_path, finished_table)
    new_spec, new_table = change(RESUMABLE, finished_table)
    spec.write_text(new_spec)
    (out / 'trials.csv').write_text(new_table)
    assert problem in one_line(sweep(str(spec), '-o', str(out), '--workers', '0', '--resume'))
    assert (out / 'trials.csv').read_text() == new_table


def test_resume_runs_a_trial_that_lacks_a_robots_row_or_a_line_end_or_failed(tmp_path, finished_table):
    """Item 9: a table cut after one robot's row of a 3-robot trial (was counted as done), a last line cut short,
    and a failed trial (was never run again): each runs again, to the rows of a sweep never interrupted."""
    spec, out = resume_case(tmp_path, finished_table)
    whole = rows_of(out / 'trials.csv')
    lines = finished_table.splitlines(keepends=True)
    (out / 'trials.csv').write_text(''.join(lines[:5]))   # trials 0-2, and trial 3's first robot only
    resumed = sweep(str(spec), '-o', str(out), '--workers', '0', '--resume')
    assert resumed.returncode == 0 and '6 trials (3 done before)' in resumed.stderr, resumed.stderr
    assert rows_of(out / 'trials.csv') == whole
    (out / 'trials.csv').write_text(''.join(lines[:3]) + lines[3][:30])
    resumed = sweep(str(spec), '-o', str(out), '--workers', '0', '--resume')
    assert resumed.returncode == 0 and '6 trials (2 done before)' in resumed.stderr, resumed.stderr
    assert rows_of(out / 'trials.csv') == whole

    (tmp_path / 'flaky.py').write_text('import os\nfrom controller import Robot\nrobot = Robot()\n'
                                       'assert not os.path.exists(os.path.join(os.path.dirname(__file__), "fail"))\n'
                                       'while robot.step(32) != -1:\n    pass\n')
    (tmp_path / 'fail').touch()
    spec.write_text('controllers: [avoid, {script: flaky.py}]\nseeds: [0]\nduration: 1\n')
    assert sweep(str(spec), '-o', str(out), '--workers', '0').returncode == 1
    (tmp_path / 'fail').unlink()
    resumed = sweep(str(spec), '-o', str(out), '--workers', '0', '--resume')
    assert resumed.returncode == 0 and '2 trials (1 done before)' in resumed.stderr, resumed.stderr
    assert [row['error'] for row in rows_of(out / 'trials.csv')] == ['', '']


def test_a_second_sweep_or_evolve_into_a_busy_folder_is_refused_and_the_first_loses_nothing(tmp_path):
    """Item 10: two sweeps into one OUT lost rows and both exited 0; now the folder is held by the first."""
    spec, out = holding_spec(tmp_path), tmp_path / 'out'
    first = subprocess.Popen([SWEEP, str(spec), '-o', str(out), '--workers', '0'], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: (tmp_path / 'started').exists(), first)
        line = one_line(sweep(str(spec), '-o', str(out), '--workers', '0', '--resume', timeout=120))
        assert 'another sweep or evolve is writing there' in line
        evolve = subprocess.run([EVOLVE, '-o', str(out), '--workers', '0', '--generations', '1', '--population',
                                 '2', '--duration', '0.1'], capture_output=True, text=True, timeout=120)
        assert 'another sweep or evolve is writing there' in one_line(evolve)
    finally:
        (tmp_path / 'hold').unlink()
    stdout, stderr = first.communicate(timeout=120)
    assert first.returncode == 0, stderr
    assert [row['trial'] for row in rows_of(out / 'trials.csv')] == ['0', '1', '2', '3']


class BannerServer:
    """A TCP port that greets each connection as an SSH server does (a banner first), then reads and drops."""

    def __init__(self) -> None:
        self.server = socket.create_server(('127.0.0.1', 0))
        self.address = f'tcp://127.0.0.1:{self.server.getsockname()[1]}'
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            try:
                connection, _ = self.server.accept()
            except OSError:   # closed
                return
            try:
                connection.sendall(b'SSH-2.0-OpenSSH_9.6p1 Ubuntu-3ubuntu13\r\n')
            except OSError:
                pass
            connection.close()

    def close(self) -> None:
        self.server.shutdown(socket.SHUT_RDWR)   # wakes the accept(); close() alone leaves it blocked
        self.server.close()
        self.thread.join(timeout=10)


def test_a_scheduler_that_is_no_dask_scheduler_is_one_line_and_leaves_out_as_it_was(tmp_path, finished_table):
    """Item 11: an SSH banner was read as a frame length ("Unable to allocate 2.82 EiB"), tls:// and ucx://
    ended in TypeErrors, and an unusable scheduler deleted OUT/trials.csv; now one line each and OUT untouched
    (with --resume too: the table holds 4 of the 6 trials, so the sweep has trials to send)."""
    spec, out = resume_case(tmp_path, ''.join(finished_table.splitlines(keepends=True)[:8]))
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    banner = BannerServer()
    try:
        for address, resume, problem in (
                (banner.address, [], "is not a Dask scheduler: it said 'SSH-2.0-'"),
                (banner.address.replace('tcp://', ''), ['--resume'], "is not a Dask scheduler: it said 'SSH-2.0-'"),
                ('tls://127.0.0.1:8786', ['--resume'], 'only tcp://HOST:PORT addresses are taken (tls://'),
                ('ucx://127.0.0.1:8786', [], 'only tcp://HOST:PORT addresses are taken (ucx://')):
            result = sweep(str(spec), '-o', str(out), '--scheduler', address, *resume, timeout=120)
            assert problem in one_line(result)
            assert {path.name: path.read_bytes() for path in out.iterdir()} == before
    finally:
        banner.close()


def special_files(tmp_path: Path) -> dict[str, Path]:
    fifo = tmp_path / 'fifo.py'
    os.mkfifo(fifo)
    (tmp_path / 'zero.py').symlink_to('/dev/zero')
    return {'/dev/zero': Path('/dev/zero'), '/dev/urandom': Path('/dev/urandom'), 'a link to /dev/zero':
            tmp_path / 'zero.py', 'a FIFO': fifo}


def test_a_script_or_spec_that_is_a_device_or_a_fifo_is_one_line(tmp_path):
    """Item 12: reading /dev/zero or /dev/urandom (or a link to one) as a script grew to gigabytes, a FIFO blocked
    for ever; scripts now get the checks worlds have (a regular file, bounded, opened without blocking), in one
    place, wherever a script is named: a spec, `webots_controller` over ROS and headless."""
    for what, path in special_files(tmp_path).items():
        spec = tmp_path / 'spec.yaml'
        spec.write_text(f'controllers: [avoid, {{script: "{path}"}}]\nseeds: [0]\nduration: 1\n')
        line = one_line(sweep(str(spec), '-o', str(tmp_path / 'out'), '--workers', '0', timeout=60))
        assert 'controllers[1].script: ' in line and 'not a regular file' in line, what
        line = one_line(sweep(str(path), '-o', str(tmp_path / 'out'), '--workers', '0', timeout=60))
        assert f'sweep: {path}: cannot read the file: not a regular file' in line, what
        over_ros = subprocess.run([CONTROLLER, str(path)], capture_output=True, text=True, timeout=60)
        assert 'not a regular file' in one_line(over_ros), what
        headless = subprocess.run([CONTROLLER, str(path), '--headless'], capture_output=True, text=True, timeout=60)
        assert headless.returncode == 2 and 'not a regular file' in headless.stderr.splitlines()[-1], what
    assert not (tmp_path / 'out').exists()


@pytest.mark.parametrize('spec_text, output, problem', [
    ('controllers: [{behaviour: [avoid]}]', 'out', "controllers[0].behaviour: expected a behaviour name, got"),
    ('controllers: [{behaviour: avoid, parameters: {cruise_speed: [1, 2]}}]', 'out',
     'controllers[0].parameters: cruise_speed: expected a number, got [1, 2]'),
    ('controllers: [{behaviour: avoid, parameters: {mode: 3}}]', 'out',
     'controllers[0].parameters: mode: expected text, got 3'),
    ('controllers: [{script: "a\\0b.py"}]', 'out', "controllers[0].script: 'a\\x00b.py': cannot read the file: "
                                                   'its name holds a NUL byte'),
    ('controllers: [avoid]', 'a_file', 'a_file: not a folder'),
    ('controllers: [avoid]', '/dev/null/out', '-o /dev/null/out: /dev/null is not a folder'),
    ('controllers: [avoid]', '/proc/out', '-o /proc/out: cannot make the folder'),
    ('controllers: [avoid]', '/sys/out', '-o /sys/out: cannot make the folder'),
    ('controllers: [avoid]', 'table_a_folder', 'table_a_folder: cannot write trials.csv: Is a directory'),
    ('controllers: [avoid]', 'table_a_folder --resume', 'trials.csv: cannot read the file: not a regular file'),
])
def test_bad_input_is_one_line_never_a_traceback(tmp_path, spec_text, output, problem):
    """Item 16: each of these was a traceback."""
    spec = tmp_path / 'spec.yaml'
    spec.write_text(f'{spec_text}\nseeds: [0]\nduration: 1\n')
    (tmp_path / 'a_file').touch()
    (tmp_path / 'table_a_folder' / 'trials.csv').mkdir(parents=True)
    result = subprocess.run([SWEEP, str(spec), '-o', *output.split(), '--workers', '0'], cwd=tmp_path,
                            capture_output=True, text=True, timeout=120)
    assert problem in one_line(result)


def test_webots_controller_record_under_a_file_is_one_line(tmp_path):
    """Item 16: `webots_controller x.py --headless --record /dev/null/x` was a traceback."""
    result = subprocess.run([CONTROLLER, str(EXAMPLE_SCRIPT), '--headless', '--duration', '1', '--record',
                             '/dev/null/x'], capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and 'Traceback' not in result.stderr
    assert result.stderr.splitlines()[-1].endswith('--record /dev/null/x: cannot write there: Not a directory')


def test_workers_are_bounded_and_never_more_than_the_trials(tmp_path):
    """Item 18: 24 workers for one trial took 69 s and 1.7 GB; 10,000 would have tried 10,000 processes."""
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [avoid]\nseeds: [0]\nduration: 1\n')
    capped = sweep(str(spec), '-o', str(tmp_path / 'out'), '--workers', '3')
    assert capped.returncode == 0 and 'on a local Dask cluster of 1 workers (one per trial to run)' in capped.stderr
    refused = sweep(str(spec), '-o', str(tmp_path / 'out'), '--workers', '10000')
    assert refused.returncode == 2 and '--workers must be at most' in refused.stderr


def test_a_recording_the_disk_cannot_hold_is_refused_before_any_trial(tmp_path, monkeypatch, capsys):
    """Item 18: --record wrote about 82 KB per robot per simulated second, unannounced; now the size is said and a
    recording larger than the free space is refused (the free space made small here)."""
    from epuck_ros.experiments import cli, record_budget
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [avoid]\nrobots: [3]\nseeds: {first: 0, count: 10}\nduration: 100\n')
    per_second, per_bag = record_budget.bag_growth()
    assert 50_000 < per_second < 200_000 and per_bag < 1_000_000
    needed = 10 * (per_bag + per_second * 3 * 100)
    monkeypatch.setattr(record_budget.shutil, 'disk_usage', lambda path: shutil._ntuple_diskusage(0, 0, needed // 2))
    with pytest.raises(SystemExit) as ended:
        cli.main([str(spec), '-o', str(tmp_path / 'out'), '--workers', '0', '--record'])
    line = capsys.readouterr().err
    assert ended.value.code == 2 and line.count('\n') == 1, line
    assert f'--record of 10 trials: about {needed / 1e6:.1f} MB' in line and 'not enough room on the disk' in line
    assert not (tmp_path / 'out').exists()


def test_an_interruption_before_any_trial_leaves_out_as_it_was(tmp_path, finished_table, monkeypatch, capsys):
    """Ctrl-C while the cluster starts: exit 130 and OUT untouched (the table there, even another spec's, was read
    and rewritten as this sweep's: a traceback)."""
    from contextlib import contextmanager

    from epuck_ros.experiments import cli

    @contextmanager
    def interrupted_start(*args, **kwargs):
        raise KeyboardInterrupt
        yield
    spec, out = resume_case(tmp_path, finished_table)
    spec.write_text(RESUMABLE.replace('[avoid]', '[spin]'))
    monkeypatch.setattr(cli, 'open_client', interrupted_start)
    with pytest.raises(SystemExit) as ended:
        cli.main([str(spec), '-o', str(out)])
    assert ended.value.code == 130 and 'interrupted before any trial ran' in capsys.readouterr().err
    assert sorted(path.name for path in out.iterdir()) == ['trials.csv']
    assert (out / 'trials.csv').read_text() == finished_table


def test_a_folder_that_fails_at_the_end_is_one_line_and_exit_1(tmp_path, monkeypatch, capsys):
    """The disk full when the picture is written: one line naming the folder, not a traceback."""
    import errno

    from epuck_ros.experiments import cli, picture

    def disk_full(rows, out):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [avoid]\nseeds: [0]\nduration: 1\n')
    monkeypatch.setattr(picture, 'draw_sweep', disk_full)
    with pytest.raises(SystemExit) as ended:
        cli.main([str(spec), '-o', str(tmp_path / 'out'), '--workers', '0'])
    err = capsys.readouterr().err
    assert ended.value.code == 1 and err.splitlines()[-1] == \
        f'sweep: -o {tmp_path / "out"}: cannot write sweep.png: No space left on device'


def test_a_table_the_disk_refuses_mid_sweep_is_one_line(tmp_path):
    """A trial's rows that the disk refuses (here /dev/full, as a full disk answers) name the folder and the file;
    the sweep then says it in one line (was an OSError's traceback)."""
    from epuck_ros.experiments.output import OutputError, OutputFolder
    from epuck_ros.experiments.table import Table
    from epuck_ros.experiments.trial import COLUMNS
    folder = OutputFolder(tmp_path)
    table = Table(folder, [])
    table._fd = os.open('/dev/full', os.O_WRONLY)
    try:
        with pytest.raises(OutputError, match='cannot write trials.csv: No space left on device'):
            table.append([dict.fromkeys(COLUMNS, '')])
    finally:
        table.close()


def test_a_recording_whose_size_cannot_be_measured_is_refused(monkeypatch):
    """The size of a recording is measured on two short ones; if they fail, the recording is refused in one line."""
    from epuck_ros.experiments import record_budget, trial
    monkeypatch.setattr(trial, 'run_trial', lambda trial: [{'error': 'OSError: No space left on device'}])
    record_budget.bag_growth.cache_clear()
    try:
        with pytest.raises(record_budget.RecordRefused, match='cannot measure what a recording takes: OSError'):
            record_budget.estimate([(1, 10.0)])
    finally:
        record_budget.bag_growth.cache_clear()
