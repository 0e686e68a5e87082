"""The sample bags in bags/ are what their commands record today (issue 33, item 13: they predated /tf, ir_raw and
lockstep_status, and `bag summary bags/avoid` said "Reproducible: unknown"). Each `record` line of
scripts/make_sample_bags.sh is run again, shortened to a fraction of a simulated second, and every topic the fresh
bag has must be in the sample: a new topic in what the command records fails here until the samples are remade."""
from __future__ import annotations

import os
import shlex
import subprocess
from pathlib import Path

import pytest
from conftest import BIN_DIR

from epuck_ros.bag.reader import Bag

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / 'scripts' / 'make_sample_bags.sh'
SHORT = '0.5'
"""Simulated seconds of each fresh run: every topic of a run is in its bag from the first steps."""


def sample_commands() -> list[tuple[str, list[str]]]:
    """(folder, arguments) of each `record FOLDER BEHAVIOUR DURATION [OPTION ...]` line of the script."""
    lines = [line for line in SCRIPT.read_text().splitlines() if line.startswith('record ')]
    return [(words[1], words[1:]) for words in map(shlex.split, lines)]


def record(arguments: list[str], folder: Path) -> None:
    """The script's own `record` function (its bringup command), run in `folder`: it writes `folder`/bags/NAME."""
    function = subprocess.run(['sed', '-n', '/^record() {/,/^}/p', str(SCRIPT)], capture_output=True, text=True,
                              check=True).stdout
    assert 'bringup' in function, function
    run = subprocess.run(['bash', '-c', f'set -euo pipefail\n{function}\nrecord "$@"', 'record', *arguments],
                         cwd=folder, capture_output=True, text=True, timeout=300,
                         env={**os.environ, 'PATH': f'{BIN_DIR}:{os.environ["PATH"]}'})
    assert run.returncode == 0, run.stdout + run.stderr


def topics(bag: Path) -> set[str]:
    with Bag(bag) as opened:
        return set(opened.topics)


def test_the_script_makes_every_sample_bag():
    samples = sorted(path.name for path in (REPO / 'bags').iterdir() if path.is_dir())
    assert sorted(folder for folder, _ in sample_commands()) == samples


@pytest.mark.parametrize('folder, arguments', sample_commands(), ids=[folder for folder, _ in sample_commands()])
def test_a_sample_bag_has_every_topic_its_command_records(folder, arguments, tmp_path):
    name, behaviour, _, *options = arguments
    (tmp_path / 'bags').mkdir()
    record([name, behaviour, SHORT, *options], tmp_path)
    missing = topics(tmp_path / 'bags' / folder) - topics(REPO / 'bags' / folder)
    assert not missing, f'bags/{folder} lacks {sorted(missing)}: remake it (scripts/make_sample_bags.sh)'
