"""The description's frame prefix (issue 28, item 6): `python -m epuck_ros.description epuck3` names frames
`epuck3/base_link`, as the simulator does."""
from __future__ import annotations

import subprocess
import sys
from io import BytesIO

import pytest
import yourdfpy

from epuck_ros import description
from epuck_ros.ros.robot_ports import frame_prefix as simulator_frame_prefix


def links_of(prefix_argument: str) -> set[str]:
    text = subprocess.run([sys.executable, '-m', 'epuck_ros.description', prefix_argument], capture_output=True,
                          text=True, check=True).stdout
    robot = yourdfpy.URDF.load(BytesIO(text.encode()), build_scene_graph=True, load_meshes=False)
    assert robot.validate()
    return set(robot.link_map)


@pytest.mark.parametrize('argument', ['epuck3', 'epuck3/'])
def test_a_robot_name_gets_its_slash(argument):
    links = links_of(argument)
    assert 'epuck3/base_link' in links and 'epuck3/ps0' in links
    assert all(link.startswith('epuck3/') for link in links), sorted(links)[:3]


def test_the_prefix_is_the_one_the_simulator_gives_a_robot_of_a_swarm():
    prefix = description.frame_prefix
    assert prefix('epuck3') == simulator_frame_prefix('epuck3', several=True) == 'epuck3/'
    assert prefix('') == '' and prefix('sim1/epuck3') == 'sim1/epuck3/'
    assert 'name="epuck3/base_link"' in description.urdf(prefix=prefix('epuck3'))


@pytest.mark.parametrize('argument', ['/epuck3', 'epuck 3', 'a//b', '3robot'])
def test_a_prefix_that_is_no_frame_prefix_is_refused_in_one_line(argument):
    run = subprocess.run([sys.executable, '-m', 'epuck_ros.description', argument], capture_output=True, text=True)
    assert run.returncode == 2 and run.stdout == ''
    assert 'a frame prefix is a robot name' in run.stderr and 'Traceback' not in run.stderr
