"""Where `bringup` finds each node's parameter table: imported from the node's own module, never copied."""
from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING

from epuck_ros.nodes.params import ParamSpec

if TYPE_CHECKING:
    from epuck_ros.bringup.cli import Plan

VIEW_HOST, VIEW_PORT = '127.0.0.1', 8765
"""The view's defaults, used only if its module does not say (its table wins)."""


def _specs(table: object) -> list[ParamSpec]:
    """A node's table as ParamSpecs (a list of them, or the older name -> (default, descriptor) dict)."""
    if isinstance(table, dict):
        specs = []
        for name, (default, descriptor) in table.items():
            ranges = list(descriptor.floating_point_range) or list(descriptor.integer_range)
            specs.append(ParamSpec(name, default, descriptor.description,
                                   (ranges[0].from_value, ranges[0].to_value) if ranges else None,
                                   descriptor.read_only))
        return specs
    return list(table)


def sim_parameters() -> list[ParamSpec]:
    from epuck_ros.nodes import sim_node
    return _specs(getattr(sim_node, 'SIM_PARAMETERS', None) or sim_node.PARAMETERS)


def behaviour_parameters(name: str) -> list[ParamSpec]:
    from epuck_ros.nodes import behaviour_nodes
    if hasattr(behaviour_nodes, 'behaviour_parameters'):
        return _specs(behaviour_nodes.behaviour_parameters(name))
    # TEMPORARY until the behaviour nodes publish their table: the settings they declare
    from epuck_ros.behaviours import BEHAVIOURS
    from epuck_ros.behaviours.base import describe
    return [ParamSpec(n, v, d, None if lo is None else (lo, hi)) for n, v, d, (lo, hi) in
            describe(BEHAVIOURS[name].defaults)] + [ParamSpec('control_period', 0.032, 'period', (0.001, 1.0))]


def controller_parameters(plan: Plan) -> list[ParamSpec] | None:
    """The controller's table; None for a student's rclpy script (its parameters are its own business)."""
    if plan.controller_kind == 'behaviour':
        return behaviour_parameters(plan.controller)
    return [] if plan.controller_kind == 'webots' else None


def view_parameters() -> list[ParamSpec]:
    try:
        view_node = importlib.import_module('epuck_ros.nodes.view_node')
    except ImportError:
        return [ParamSpec('host', VIEW_HOST, 'address the page is served on'),
                ParamSpec('port', VIEW_PORT, 'TCP port of the page', (1, 65535))]
    return _specs(getattr(view_node, 'VIEW_PARAMETERS', None) or view_node.PARAMETERS)


def view_url(assignments: list[str]) -> str:
    """The page's address from the view's parameters (overrides, else its defaults)."""
    values = {spec.name: spec.default for spec in view_parameters()}
    for assignment in assignments:
        name, _, value = assignment.partition(':=')
        values[name] = value.strip('\'"')
    return f'http://{values.get("host", VIEW_HOST)}:{values.get("port", VIEW_PORT)}/'


def default_bag_folder() -> Path:
    from epuck_ros.nodes.record_node import default_output
    return default_output()
