"""A swarm split over two hosts: `sim` in one network namespace, `avoid --robots all` in another, joined only by a
veth pair, with DDS discovery confined to that link (ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET, UDP only: no shared
memory between the two). The robots drive in lockstep across the link: their ground truth is that of the same
trial run headless in this process (`experiments.trial`, equal to `bringup --lockstep` to the bit), and the
traffic went over the veth. Root only (network namespaces); the namespaces go whatever happens.
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
import textwrap
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from epuck_ros.bringup.processes import executable, interrupt
from epuck_ros.experiments.trial import Controller, Trial, run

ROBOTS, SEED, DURATION = 3, 2, 1.0
SUBNET = '10.77.0.{}/24'
LINK_ENV = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET', 'FASTDDS_BUILTIN_TRANSPORTS': 'UDPv4'}
"""Discovery on the namespace's subnet, i.e. the veth; UDP only, so nothing goes through shared memory."""

PROBE = '''
import json, sys
from epuck_ros.testing.simulator import SimulatorUnderTest
sim = SimulatorUnderTest(robots={robots}, seed={seed}, env={env!r}, log_dir={log_dir!r})
try:
    print(json.dumps({{'domain': sim.domain}}), flush=True)
    sim.wait_for_controller(timeout=120)
    print(json.dumps({{'connected': True}}), flush=True)
    sys.stdin.readline()
    sim.run_until({duration})
    print(json.dumps({{'time': sim.time, 'truth': [sim.ground_truth(n) for n in sim.names]}}), flush=True)
finally:
    sim.stop()
'''


def _ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(['ip', *args], capture_output=True, text=True, timeout=30)


@pytest.fixture
def two_hosts() -> Iterator[tuple[str, str]]:
    """Two network namespaces joined by a veth pair (10.77.0.1 and .2); removed however the test ends."""
    if os.geteuid() != 0 or shutil.which('ip') is None:
        pytest.skip('needs root and iproute2 (`ip netns`) to make two network namespaces')
    tag = uuid.uuid4().hex[:8]
    hosts = (f'epuck-{tag}-a', f'epuck-{tag}-b')
    links = (f've{tag}a', f've{tag}b')
    made: list[str] = []
    try:
        for host in hosts:
            if _ip('netns', 'add', host).returncode != 0:
                pytest.skip(f'cannot make a network namespace here: {_ip("netns", "add", host).stderr.strip()}')
            made.append(host)
        steps = [('link', 'add', links[0], 'netns', hosts[0], 'type', 'veth', 'peer', 'name', links[1], 'netns',
                  hosts[1])]
        for index, (host, link) in enumerate(zip(hosts, links)):
            steps += [('-n', host, 'addr', 'add', SUBNET.format(index + 1), 'dev', link),
                      ('-n', host, 'link', 'set', 'lo', 'up'), ('-n', host, 'link', 'set', link, 'up'),
                      ('-n', host, 'route', 'add', '224.0.0.0/4', 'dev', link)]   # DDS discovery is multicast
        for step in steps:
            done = _ip(*step)
            assert done.returncode == 0, f'ip {" ".join(step)}: {done.stderr}'
        yield hosts
    finally:
        for host in made:
            _ip('netns', 'delete', host)   # deletes its end of the veth, and so the pair


def _bytes_over(host: str, link: str) -> int:
    statistics = [_ip('netns', 'exec', host, 'cat', f'/sys/class/net/{link}/statistics/{way}_bytes').stdout
                  for way in ('rx', 'tx')]
    return sum(int(value) for value in statistics)


def test_a_swarm_split_over_two_hosts_runs_in_lockstep(two_hosts, tmp_path):
    sim_host, controller_host = two_hosts
    link = 've' + sim_host.split('-')[1] + 'a'
    probe = subprocess.Popen(
        ['ip', 'netns', 'exec', sim_host, sys.executable, '-c', textwrap.dedent(PROBE).format(
            robots=ROBOTS, seed=SEED, env=LINK_ENV, log_dir=str(tmp_path), duration=DURATION)],
        env=dict(os.environ, **LINK_ENV), stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
        text=True, start_new_session=True)
    controller = None
    try:
        first = probe.stdout.readline()
        assert first.startswith('{'), first + probe.stdout.read()
        domain = json.loads(first)['domain']
        controller = subprocess.Popen(
            ['ip', 'netns', 'exec', controller_host, executable('avoid'), '--robots', 'all', '--ros-args', '-p',
             'use_sim_time:=true'], env=dict(os.environ, ROS_DOMAIN_ID=str(domain), **LINK_ENV),
            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT, start_new_session=True)
        connected = probe.stdout.readline()
        assert connected.startswith('{'), connected + probe.stdout.read()
        before = _bytes_over(sim_host, link)   # discovery is done: what crosses from now on is the run
        probe.stdin.write('run\n')
        probe.stdin.flush()
        last = probe.stdout.readline()
        assert last.startswith('{'), last + probe.stdout.read() + Path(tmp_path).joinpath(
            f'sim-domain{domain}.log').read_text()
        result = json.loads(last)
        crossed = _bytes_over(sim_host, link) - before
    finally:
        if controller is not None:
            interrupt(controller, 10.0)
        interrupt(probe, 30.0)
    headless, _ = run(Trial(Controller('avoid'), robots=ROBOTS, seed=SEED, duration=DURATION))
    assert result['time'] == pytest.approx(headless.time, abs=1e-9)
    for (x, y, yaw), expected, start in zip(result['truth'], headless.true_pose.tolist(),
                                            headless.world.robots):
        assert math.dist((x, y), start.pose[:2]) > 0.03, 'the robot drove'
        assert (x, y) == tuple(expected[:2]), 'the same run as in lockstep on one machine, to the bit'
        assert yaw == pytest.approx(expected[2], abs=1e-12)
    steps = round(DURATION / 0.032)
    # every step: the swarm observation (20 numbers a robot) and /clock out to the controller, the swarm command
    # back, as UDP over the veth (at least 160 bytes a robot of numbers alone; shared memory would leave only
    # acknowledgements on the link)
    assert crossed > steps * ROBOTS * 200, f'only {crossed} bytes crossed the link during the run'
