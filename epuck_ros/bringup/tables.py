"""Where `bringup` finds each node's parameter table: imported from the node's own module, never copied."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from epuck_ros.nodes.params import ParamSpec

if TYPE_CHECKING:
    from epuck_ros.bringup.cli import Plan


def sim_parameters() -> list[ParamSpec]:
    from epuck_ros.nodes.sim_node import SIM_PARAMETERS
    return list(SIM_PARAMETERS)


def sim_default(name: str) -> object:
    """The default of one of the simulator's parameters."""
    return next(spec.default for spec in sim_parameters() if spec.name == name)


def controller_parameters(plan: Plan) -> list[ParamSpec] | None:
    """The controller's table; None for a student's rclpy script (its parameters are its own business)."""
    if plan.controller_kind == 'behaviour':
        from epuck_ros.behaviours import BEHAVIOURS
        from epuck_ros.nodes.behaviour_nodes import parameter_specs
        return parameter_specs(BEHAVIOURS[plan.controller])
    return [] if plan.controller_kind == 'webots' else None


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
