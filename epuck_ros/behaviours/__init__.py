"""The course behaviours as pure state machines (Observation -> WheelCommand), and the table of executables.

`BEHAVIOURS` maps each executable name to its behaviour class and default settings; the node module builds
every executable from it, the tests build the same objects.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from epuck_ros.behaviours.avoid import Avoid, AvoidConfig
from epuck_ros.behaviours.base import STOP, Behaviour, Config, ConfigError, Observation, WheelCommand
from epuck_ros.behaviours.forward import Forward, ForwardConfig
from epuck_ros.behaviours.open_loop import CIRCLE, SPIN, OpenLoop
from epuck_ros.behaviours.rectangle import Rectangle, RectangleConfig


@dataclass(frozen=True)
class BehaviourSpec:
    """An executable's behaviour: its class and its default settings (their fields become ROS parameters)."""

    make: Callable[[Config], Behaviour]
    defaults: Config
    summary: str
    example: str = ''
    """Typical `-p NAME:=VALUE` settings for the executable's --help."""


BEHAVIOURS: dict[str, BehaviourSpec] = {
    'forward': BehaviourSpec(Forward, ForwardConfig(), 'controller_1: straight ahead, optionally to a goal',
                             '-p goal_distance:=0.3'),
    'spin': BehaviourSpec(OpenLoop, SPIN, 'controller_2: rotation in place', '-p left:=0.3 -p right:=-0.3'),
    'circle': BehaviourSpec(OpenLoop, CIRCLE, 'controller_3: circle of radius 0.078 m', '-p left:=0.2 -p right:=0.4'),
    'rectangle': BehaviourSpec(Rectangle, RectangleConfig(), 'controller_4: sides and in-place corners',
                               '-p side_a:=0.2 -p laps:=1'),
    'avoid': BehaviourSpec(Avoid, AvoidConfig(), 'obstacle avoidance on the IR ranges',
                           '-p mode:=braitenberg -p cruise_speed:=0.4'),
}

__all__ = ['BEHAVIOURS', 'STOP', 'Avoid', 'AvoidConfig', 'Behaviour', 'BehaviourSpec', 'Config', 'ConfigError',
           'Forward', 'ForwardConfig', 'Observation', 'OpenLoop', 'Rectangle', 'RectangleConfig', 'WheelCommand']
