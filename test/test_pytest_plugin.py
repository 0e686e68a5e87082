"""The `epuck_sim` pytest plugin as a user meets it: a throwaway project of its own (the manual's example test, which
passes, and a test that fails), run by pytest in a subprocess; afterwards no process of that run is left."""
from __future__ import annotations

import os
import re
import subprocess
import sys
import uuid
from importlib.metadata import entry_points
from pathlib import Path

import domain_coordinator
import pytest
from conftest import BIN_DIR
from manual_pages import blocks

from epuck_ros.testing.simulator import DOMAIN_RANGE_VARIABLE, NoFreeDomain, claim_free_domain

FAILING = '''
from pathlib import Path


def test_fails_after_starting_a_simulator(epuck_sim):
    sim = epuck_sim(seed=4)
    Path('sim.pid').write_text(str(sim.process.pid))
    assert sim.contacts() == 1, 'fails on purpose'
'''


def readme_example() -> str:
    """The manual's ```python block that uses the fixture (docs/ros-graph.md)."""
    found = [block for block in blocks('python') if 'epuck_sim' in block]
    assert len(found) == 1, 'the manual shows one test with epuck_sim'
    return found[0]


def processes_with(marker: str) -> list[int]:
    """Processes whose environment holds `marker` (every process the run started inherits it)."""
    found = []
    for entry in Path('/proc').iterdir():
        if entry.name.isdigit() and int(entry.name) != os.getpid():
            try:
                if marker.encode() in (entry / 'environ').read_bytes():
                    found.append(int(entry.name))
            except OSError:   # gone meanwhile, or not ours to read
                pass
    return found


def test_a_users_project_passes_and_fails_with_nothing_left_running(tmp_path):
    project = tmp_path / 'user_project'
    project.mkdir()
    example = readme_example()
    assert len(example.strip().splitlines()) <= 12, 'a short example'
    (project / 'test_readme_example.py').write_text(example)
    (project / 'test_failing.py').write_text(FAILING)
    marker = f'EPUCK_PLUGIN_RUN={uuid.uuid4().hex}'
    name, value = marker.split('=')
    installed = any(ep.name == 'epuck_ros' for ep in entry_points(group='pytest11'))
    plugin = [] if installed else ['-p', 'epuck_ros.testing.plugin']   # until the entry point is installed
    # The venv not activated (`.venv/bin/python -m pytest`): its scripts are not on PATH, and the example runs
    # `forward` (issue 33 item 15: FileNotFoundError: 'forward'); sim.env puts this Python's scripts first.
    path = os.pathsep.join(folder for folder in os.environ['PATH'].split(os.pathsep)
                           if folder and Path(folder).resolve() != BIN_DIR.resolve())
    env = dict(os.environ, PATH=path, **{name: value})
    run = subprocess.run([sys.executable, '-m', 'pytest', *plugin, '-p', 'no:cacheprovider', '-q', '-rA'],
                         cwd=project, env=env, capture_output=True, text=True, timeout=300)
    output = run.stdout + run.stderr
    assert run.returncode == 1, output
    assert re.search(r'\b1 failed, 1 passed\b', output), output
    assert 'PASSED test_readme_example.py' in output and 'fails on purpose' in output, output
    sim_pid = int((project / 'sim.pid').read_text())
    assert not Path(f'/proc/{sim_pid}').exists(), 'the failing test\'s simulator was stopped'
    assert processes_with(marker) == [], 'no process of the run is left'


def test_a_simulators_domain_is_claimed_as_the_test_runs_claim_theirs():
    """The fixture's domain and a `domain_coordinator` claim (this test run's, a user's fixture) never coincide."""
    domain, claim = claim_free_domain()
    try:
        assert 1 <= domain <= 100 and str(domain) != os.environ['ROS_DOMAIN_ID']
        with pytest.raises(RuntimeError), domain_coordinator.domain_id(lambda: domain):
            pass
    finally:
        claim.__exit__(None, None, None)
    with domain_coordinator.domain_id(lambda: domain) as again:
        assert again == domain, 'freed at the end of the claim'


def test_the_domains_claimed_are_confined_to_a_range(monkeypatch):
    """Issue 33 item 15: the fixture picked domains 1-100 with no way to confine it. EPUCK_ROS_DOMAIN_RANGE=FIRST-LAST
    does (test/conftest.py reads it too); every domain of it held is a NoFreeDomain naming the range; a malformed
    range is a ValueError naming the variable."""
    monkeypatch.setenv(DOMAIN_RANGE_VARIABLE, '150-151')
    domain, claim = claim_free_domain()
    try:
        assert domain in (150, 151)
        other, other_claim = claim_free_domain()
        try:
            assert {domain, other} == {150, 151}
            with pytest.raises(NoFreeDomain, match=f'no free ROS domain in {DOMAIN_RANGE_VARIABLE}=150-151'):
                claim_free_domain()
        finally:
            other_claim.__exit__(None, None, None)
    finally:
        claim.__exit__(None, None, None)
    for bad in ('150', '151-150', 'a-b', '0-233', '٣-5'):
        monkeypatch.setenv(DOMAIN_RANGE_VARIABLE, bad)
        with pytest.raises(ValueError, match=DOMAIN_RANGE_VARIABLE):
            claim_free_domain()
