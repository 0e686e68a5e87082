"""The figures `bringup` prints at the end of a run, by the same code as `bag summary` (`run_summary.RunTally`):
from the bag when the run was recorded, else from the ground-truth samples `bringup` received. One source of
truth for distance and contacts, and one format (`run_summary.format_figures`)."""
from __future__ import annotations

from pathlib import Path

from epuck_ros.bag.reader import Bag
from epuck_ros.bag.run_summary import RobotFigures, format_figures, load_runs, tally_runs


def from_bag(path: Path) -> list[RobotFigures]:
    """Each recorded robot's figures, as `bag summary` computes them."""
    with Bag(path) as bag:
        return tally_runs(load_runs(bag)).figures


def lines(figures: list[RobotFigures]) -> list[str]:
    """One line per robot."""
    return format_figures(figures).splitlines()
