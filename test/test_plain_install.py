"""A user's `pip install .` (no extras) into a fresh venv is enough for the `epuck_sim` fixture that the install
registers: the README's fixture example passes there, with pytest, the user's own test runner, beside it.

Cost: a couple of minutes of one core (a venv of about a hundred packages, ROS 2 Jazzy's wheels among them), plus
the download on the first run on a machine. Marked `slow`: `scripts/test.sh --slow` and .ci/run run it, plain
`scripts/test.sh` does not. The wheels are kept in a wheelhouse (WHEELHOUSE) that later runs install from without
the index (pip's own HTTP cache keeps nothing here); what the wheelhouse lacks is fetched once with `pip download`,
which resolves the same requirements `pip install .` does.
"""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
from test_pytest_plugin import processes_with, readme_example

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_FILES = ('setup.py', 'setup.cfg', 'package.xml', 'resource', 'epuck_ros')
"""What `pip install .` reads: copied, so that its build leaves nothing in the checkout."""
WHEELHOUSE = Path(os.environ.get('XDG_CACHE_HOME', Path.home() / '.cache')) / 'epuck_ros' / 'wheelhouse'
TOOLS = ('setuptools', 'wheel', 'pytest')
"""Besides the package's own requirements: what pip builds it with (build isolation), and the user's test runner."""
INSTALL_TIMEOUT = 1800.0
"""Wall seconds for a download or an install at most (a fresh machine's download included); decides nothing."""


def pip(python: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(python), '-m', 'pip', '--disable-pip-version-check', *args], capture_output=True,
                          text=True, timeout=INSTALL_TIMEOUT)


def install_offline(python: Path, *requirements: str) -> subprocess.CompletedProcess:
    return pip(python, 'install', '--no-index', '--find-links', str(WHEELHOUSE), *requirements)


@pytest.mark.slow
def test_the_fixture_works_from_a_plain_pip_install(tmp_path):
    source = tmp_path / 'epuck_ros'
    source.mkdir()
    for name in PACKAGE_FILES:
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns('__pycache__'))
        else:
            shutil.copy2(ROOT / name, source / name)
    venv = tmp_path / 'venv'
    subprocess.run([sys.executable, '-m', 'venv', str(venv)], check=True, timeout=300)
    python = venv / 'bin' / 'python'
    WHEELHOUSE.mkdir(parents=True, exist_ok=True)
    with open(WHEELHOUSE / '.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)   # another test run filling the wheelhouse at the same time
        tools = install_offline(python, *TOOLS)
        if tools.returncode != 0:
            fetched = pip(python, 'download', '--dest', str(WHEELHOUSE), str(source), *TOOLS)
            assert fetched.returncode == 0, fetched.stdout + fetched.stderr
            tools = install_offline(python, *TOOLS)
        assert tools.returncode == 0, tools.stdout + tools.stderr
        installed = install_offline(python, str(source))
        if installed.returncode != 0:
            fetched = pip(python, 'download', '--dest', str(WHEELHOUSE), str(source))
            assert fetched.returncode == 0, fetched.stdout + fetched.stderr
            installed = install_offline(python, str(source))
    assert installed.returncode == 0, installed.stdout + installed.stderr
    listed = pip(python, 'list', '--format=freeze').stdout
    assert 'epuck-ros==' in listed.replace('_', '-') and 'websocket-client' not in listed, 'no test extra'

    project = tmp_path / 'user_project'
    project.mkdir()
    (project / 'test_readme_example.py').write_text(readme_example())
    marker = f'EPUCK_PLAIN_INSTALL_RUN={uuid.uuid4().hex}'
    name, value = marker.split('=')
    env = {key: value for key, value in os.environ.items() if key not in ('PYTHONPATH', 'VIRTUAL_ENV')}
    env.update({'PATH': f'{venv / "bin"}{os.pathsep}{os.environ["PATH"]}', 'VIRTUAL_ENV': str(venv),
                'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', name: value})
    run = subprocess.run([str(python), '-m', 'pytest', '-p', 'no:cacheprovider', '-q', '-rA'], cwd=project, env=env,
                         capture_output=True, text=True, timeout=600)
    output = run.stdout + run.stderr
    assert run.returncode == 0 and 'PASSED test_readme_example.py' in output, output
    assert processes_with(marker) == [], 'no process of the run is left'
