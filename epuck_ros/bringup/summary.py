"""The figures `bringup` prints at the end of a run, computed by the same code as `bag summary`
(`epuck_ros.bag.run_summary.summarise`), from the bag when the run was recorded, else from the ground-truth
samples `bringup` received: one source of truth for distance and collisions.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from epuck_ros.bag import run_summary
from epuck_ros.bag.reader import Bag
from epuck_ros.bringup.monitor import RobotTrack
from epuck_ros.world import World


@dataclass(frozen=True)
class RobotFigures:
    name: str
    distance: float
    collisions: int | None


def from_bag(path: Path) -> list[RobotFigures]:
    """Each recorded robot's figures, as `bag summary` reports them."""
    with Bag(path) as bag:
        return [_figures(namespace.strip('/') or 'epuck', run_summary.load_run(bag, namespace))
                for namespace in run_summary.robot_namespaces(bag)]


def from_tracks(tracks: dict[str, RobotTrack], world: World | None) -> list[RobotFigures]:
    """Each robot's figures from the ground-truth samples received during the run."""
    figures = []
    for name, track in tracks.items():
        if not track.rows:
            figures.append(RobotFigures(name, 0.0, 0))
            continue
        origin = min(row[0] for row in track.rows)
        truth = run_summary._trajectory('ground_truth', track.rows, origin)
        run = run_summary.RunData(bag_path='', namespace=name, trajectory=truth, truth=truth, odom=None,
                                  ranges=None, world=world, closed_properly=True)
        figures.append(_figures(name, run))
    return figures


def _figures(name: str, run: run_summary.RunData) -> RobotFigures:
    summary = run_summary.summarise(run)
    return RobotFigures(name, summary.distance, summary.collisions)


def table(figures: list[RobotFigures]) -> list[str]:
    """A compact per-robot table, one line per robot, with the total."""
    width = max(len('robot'), *(len(f.name) for f in figures))
    lines = [f'{"robot":<{width}}  distance (m)  collisions']
    for f in figures:
        lines.append(f'{f.name:<{width}}  {f.distance:12.3f}  {"?" if f.collisions is None else f.collisions:>10}')
    known = [f.collisions for f in figures if f.collisions is not None]
    lines.append(f'{"total":<{width}}  {sum(f.distance for f in figures):12.3f}  {sum(known):>10}')
    return lines

