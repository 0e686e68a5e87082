"""Where `bringup` finds each node's parameter table: imported from the node's own module, never copied.

Each node module is imported only when its table is asked for, so `bringup --help` loads none of them.
"""
from __future__ import annotations

from pathlib import Path

from epuck_ros.ros.params import ParamSpec


def sim_parameters() -> list[ParamSpec]:
    from epuck_ros.nodes.sim_node import SIM_PARAMETERS
    return list(SIM_PARAMETERS)


def sim_default(name: str) -> object:
    """The default of one of the simulator's parameters."""
    return next(spec.default for spec in sim_parameters() if spec.name == name)


def controller_parameters(kind: str, controller: str) -> list[ParamSpec] | None:
    """The table of a controller of `kind` ('behaviour', 'webots', 'rclpy'); None for a student's rclpy script
    (its parameters are its own business)."""
    if kind == 'behaviour':
        from epuck_ros.behaviours import BEHAVIOURS
        from epuck_ros.nodes.behaviour_nodes import parameter_specs
        return parameter_specs(BEHAVIOURS[controller])
    return [] if kind == 'webots' else None


def view_parameters() -> list[ParamSpec]:
    from epuck_ros.nodes.view_node import PARAMETERS
    return list(PARAMETERS)


def view_url(assignments: list[str]) -> str:
    """The page's address from the view's parameters (overrides, else its defaults); '' when the view picks a free
    port itself (port 0), which only its own `view:` line can tell."""
    values = {spec.name: spec.default for spec in view_parameters()}
    for assignment in assignments:
        name, _, value = assignment.partition(':=')
        values[name] = value.strip('\'"')
    return '' if str(values['port']) == '0' else f'http://{values["host"]}:{values["port"]}/'


def default_bag_folder() -> Path:
    from epuck_ros.nodes.record_node import default_output
    return default_output()
