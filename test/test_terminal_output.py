"""What the terminal shows (issue 28, item 4): a first set-up says what it is doing, and a run's terminal is readable.

`scripts/setup.sh` spent minutes in a quiet pip: a line per phase with its time. `bringup` printed one line into
another (print() writes a line and its newline apart, from several threads) and flooded the terminal with every
behaviour state change: every line is now written whole, state changes are DEBUG lines that `--verbose` shows.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FAKE_PYTHON = '''#!/usr/bin/env bash
# Stands in for python3 (and, once copied, for the venv's python): pip and imports succeed at once.
case "$1" in
  --version) echo "Python 3.99.0" ;;
  -m) if [ "$2" = venv ]; then mkdir -p "$3/bin" && cp "$0" "$3/bin/python"
      else echo "$*" >> "$(dirname "$0")/calls"; fi ;;
  -c) exit 0 ;;
esac
'''


def setup_checkout(tmp_path: Path) -> Path:
    """A scratch copy of the set-up scripts and the files whose hash decides a reinstall."""
    checkout = tmp_path / 'checkout'
    shutil.copytree(ROOT / 'scripts', checkout / 'scripts', ignore=shutil.ignore_patterns('tf2_msgs'))
    for name in ('requirements.txt', 'setup.py', 'setup.cfg', 'package.xml'):
        shutil.copy(ROOT / name, checkout / name)
    fake = tmp_path / 'python3'
    fake.write_text(FAKE_PYTHON)
    fake.chmod(0o755)
    return fake


def test_setup_says_each_phase_and_how_long_it_took(tmp_path):
    fake = setup_checkout(tmp_path)
    run = subprocess.run(['bash', str(tmp_path / 'checkout' / 'scripts' / 'setup.sh')], capture_output=True,
                         text=True, env=dict(os.environ, PYTHON=str(fake)), timeout=120)
    assert run.returncode == 0, run.stderr
    lines = run.stderr.splitlines()
    for phase in ('1/4 creating .venv with Python 3.99.0', '2/4 upgrading pip', '3/4 installing ROS 2 Jazzy',
                  '4/4 installing epuck_ros'):
        begins = [i for i, line in enumerate(lines) if line.startswith(f'[setup] {phase}')]
        number = phase.split()[0]
        ends = [i for i, line in enumerate(lines) if re.fullmatch(rf'\[setup\] {number} done in \d+ s', line)]
        assert len(begins) == len(ends) == 1 and begins[0] < ends[0], (phase, lines)
    assert re.fullmatch(r'\[setup\] \.venv ready in \d+ s', lines[-1]), lines
    calls = (tmp_path / 'checkout' / '.venv' / 'bin' / 'calls').read_text().splitlines()
    assert [call.split()[:4] for call in calls] == [['-m', 'pip', 'install', '--quiet']] * 3
    again = subprocess.run(['bash', str(tmp_path / 'checkout' / 'scripts' / 'setup.sh')], capture_output=True,
                           text=True, env=dict(os.environ, PYTHON=str(fake)), timeout=120)
    assert again.returncode == 0 and again.stderr == '', 'set up already: nothing to say'


RECORDING_RUN = '''
import json, sys


class Writes:
    """A stream that keeps each write() call: a line written in two calls can be split by another thread's."""

    def __init__(self):
        self.calls = []

    def write(self, text):
        self.calls.append(text)
        return len(text)

    def flush(self):
        pass

    def fileno(self):   # faulthandler (rclpy's EventsExecutor enables it) writes to the real stderr
        return 2


out, err = Writes(), Writes()
sys.stdout, sys.stderr = out, err
from epuck_ros.bringup.run import main
try:
    main(sys.argv[2:])
except SystemExit as end:
    code = end.code
with open(sys.argv[1], 'w') as report:
    json.dump({'code': code, 'out': out.calls, 'err': err.calls}, report)
'''


def bringup_writes(tmp_path: Path, *options: str) -> dict:
    """`bringup` in a process of its own whose stdout and stderr keep every write() call."""
    report = tmp_path / f'writes{len(list(tmp_path.iterdir()))}.json'
    subprocess.run([sys.executable, '-c', RECORDING_RUN, str(report), 'avoid', '--robots', '2', '--duration', '2',
                    '--real-time-factor', '0', '--seed', '1', *options], timeout=300, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return json.loads(report.read_text())


@pytest.mark.parametrize('verbose', [False, True])
def test_bringup_writes_whole_lines_and_state_changes_only_when_verbose(tmp_path, verbose):
    writes = bringup_writes(tmp_path, *(['--verbose'] if verbose else []))
    assert writes['code'] == 0, writes
    torn = [call for call in writes['out'] + writes['err'] if not call.endswith('\n') or call.count('\n') != 1]
    assert torn == [], f'every write is one whole line: {torn[:5]}'
    lines = ''.join(writes['out']).splitlines()
    assert any(line.startswith('[bringup] running avoid on 2 robots') for line in lines)
    assert all(line.startswith(('[bringup] ', '[sim] ', '[avoid] ')) for line in lines), lines
    # One avoid drives both robots through the swarm topics: its node says its settings once, and each robot's state
    # changes, named by the robot, only at DEBUG (--verbose).
    states = [line for line in lines if re.search(r'\]: epuck\d: (cruising|front obstacle: turning \w+ until clear) '
                                                  r'\(t=', line)]
    settings = [line for line in lines if 'obstacle avoidance on the IR ranges; mode=rules' in line]
    assert len(settings) == 1 and '[INFO]' in settings[0] and '2 robots through /swarm/observation' in settings[0], \
        settings
    if verbose:
        assert states and all('[DEBUG]' in line for line in states), states
        assert {re.search(r'\]: (epuck\d): ', line).group(1) for line in states} == {'epuck0', 'epuck1'}
    else:
        assert states == [], states
