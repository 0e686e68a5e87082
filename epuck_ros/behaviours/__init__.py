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


BEHAVIOURS: dict[str, BehaviourSpec] = {
    'forward': BehaviourSpec(Forward, ForwardConfig(), 'controller_1: straight ahead, optionally to a goal'),
    'spin': BehaviourSpec(OpenLoop, SPIN, 'controller_2: rotation in place'),
    'circle': BehaviourSpec(OpenLoop, CIRCLE, 'controller_3: circle of radius 0.078 m'),
    'rectangle': BehaviourSpec(Rectangle, RectangleConfig(), 'controller_4: sides and in-place corners'),
    'avoid': BehaviourSpec(Avoid, AvoidConfig(), 'obstacle avoidance on the IR ranges'),
}

__all__ = ['BEHAVIOURS', 'STOP', 'Avoid', 'AvoidConfig', 'Behaviour', 'BehaviourSpec', 'Config', 'ConfigError',
           'Forward', 'ForwardConfig', 'Observation', 'OpenLoop', 'Rectangle', 'RectangleConfig', 'WheelCommand']
