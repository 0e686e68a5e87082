"""Every installed executable answers --help with its usage and exits 0, without starting anything."""
import re
import subprocess
from pathlib import Path

import pytest
from conftest import BIN_DIR, processes_in_this_domain

SETUP = Path(__file__).resolve().parents[1] / 'setup.py'
EXECUTABLES = re.findall(r"'(\w+) = epuck_ros\.", SETUP.read_text().split("'console_scripts'")[1].split(']')[0])


def test_the_executables_are_found():
    assert {'sim', 'avoid', 'bringup', 'record', 'bag', 'view', 'teleop', 'webots_controller'} <= set(EXECUTABLES)


@pytest.mark.parametrize('name', EXECUTABLES)
def test_help_prints_the_usage_and_exits_0(name: str) -> None:
    result = subprocess.run([str(BIN_DIR / name), '--help'], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith(f'usage: {name}'), result.stdout
    assert 'Traceback' not in result.stdout + result.stderr
    assert processes_in_this_domain() == []
