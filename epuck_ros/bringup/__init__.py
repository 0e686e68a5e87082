"""`bringup`: the simulator, a controller and optionally the recorder and the view, as separate processes.

ROS 2 launch is not available from PyPI, so this package does its job (see `bringup --help`):

- `cli`: options and `-p` assignments, checked against each node's parameter table before anything starts;
- `processes`: children that end with `bringup` however it ends (`watchdog` is the guard process);
- `monitor`: `bringup`'s node: readiness from the graph, simulated time, every robot's ground truth;
- `summary`: the end-of-run figures, by the same code as `bag summary`;
- `run`: start, resume, watch, stop.
"""
from __future__ import annotations


def main(argv: list[str] | None = None) -> None:
    """The `bringup` executable (imported lazily: the watchdog shares this package but must not load ROS)."""
    from epuck_ros.bringup.run import main as run_main
    run_main(argv)
