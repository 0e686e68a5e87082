"""The package passes flake8 and pep257-style docstring checks, as ament_flake8 and ament_pep257 check a ROS package.

flake8's configuration is in setup.cfg, pydocstyle's in .pydocstyle (the convention, ament_pep257's ignores and
this package's few more, each with its reason).
"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
CHECKED = ['epuck_ros', 'test', 'benchmarks', 'setup.py']


def test_flake8_finds_nothing():
    result = subprocess.run([sys.executable, '-m', 'flake8', *CHECKED],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr


def test_pydocstyle_finds_nothing():
    result = subprocess.run([sys.executable, '-m', 'pydocstyle', *CHECKED],
                            cwd=REPO, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
