"""The package passes flake8 with the configuration in setup.cfg, as ament_flake8 checks a ROS package in CI."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def test_flake8_finds_nothing():
    result = subprocess.run([sys.executable, '-m', 'flake8', 'epuck_ros', 'test', 'benchmarks', 'setup.py'],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
