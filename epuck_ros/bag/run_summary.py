"""What a course user (or teacher) wants to know about a recorded e-puck run, for one robot or many.

Duration, distance travelled, mean speed, the closest approach the IR sensors saw, contacts with walls
and obstacles and with other robots, where each robot ended (its final pose), and what kind of run it was with
that shape's figures only. The parts: `runs` (reading a bag), `tally` (distance, contacts and final pose, shared
with `bringup`), `shapes` (what the run was) and `summary_text` (the text, above this module: it formats these
summaries); the names of all but the text stay importable from here.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from epuck_ros.bag.runs import (ODOMETRY, RANGE, STRING, TRAJECTORY_TOPICS, RunData, Trajectory, load_run, load_runs,
                                robot_namespaces, start_pose)
from epuck_ros.bag.shapes import (CIRCLE_RMS_RATIO, CORNER_RANGE_DEG, MIN_CORNER_DEG, MIN_SEGMENT_TIME, MIN_SIDE_RATIO,
                                  MOVING_SPEED, STILL_DISTANCE, STRAIGHT_YAW_RATE, CircleFit, Corners, Motion, Spin,
                                  StraightLine, classify, classify_recorded, fit_circle, straight_segments)
from epuck_ros.bag.tally import (CONTACT_MARGIN, SLIP_RATIO, Contact, RobotFigures, RunTally, contacts_from_slip,
                                 tally_runs)
from epuck_ros.model import RobotModel

__all__ = ['CIRCLE_RMS_RATIO', 'CONTACT_MARGIN', 'CORNER_RANGE_DEG', 'MIN_CORNER_DEG', 'MIN_SEGMENT_TIME',
           'MIN_SIDE_RATIO', 'MOVING_SPEED', 'ODOMETRY', 'RANGE', 'SLIP_RATIO', 'STILL_DISTANCE', 'STRAIGHT_YAW_RATE',
           'STRING', 'TRAJECTORY_TOPICS', 'BagSummary', 'CircleFit', 'Contact',
           'Corners', 'Motion', 'RobotFigures', 'RunData', 'RunSummary', 'RunTally', 'Spin', 'StraightLine',
           'Trajectory', 'classify', 'contacts_from_slip', 'fit_circle', 'load_run', 'load_runs',
           'robot_namespaces', 'start_pose', 'straight_segments', 'summarise', 'summarise_runs', 'tally_runs']


@dataclass
class RunSummary:
    bag: str
    namespace: str
    trajectory_topic: str
    motion: str
    duration: float
    distance: float
    mean_speed: float
    closest_approach: float | None
    closest_sensor: str | None
    closest_time: float | None
    collisions: int | None
    """Contacts with walls and obstacles."""
    collisions_from: str
    robot_collisions: int | None
    """Contacts with other robots (None in a one-robot bag)."""
    straight: StraightLine | None
    spin: Spin | None
    circle: CircleFit | None
    corners: Corners | None
    closed_properly: bool
    final_pose: tuple[float, float, float] | None
    """(x, y, yaw in [-pi, pi]) of the last ground-truth sample (None without ground truth)."""
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class BagSummary:
    """Every robot's summary, and what involves several of them."""

    bag: str
    robots: list[RunSummary]
    robot_robot_contacts: int | None
    """Contacts between two robots, each counted once (None in a one-robot bag)."""
    contacts: list[Contact]
    """Where each contact began, for the plot."""

    def to_dict(self) -> dict:
        if len(self.robots) == 1:
            return self.robots[0].to_dict()
        return {'bag': self.bag, 'robots': [r.to_dict() for r in self.robots],
                'robot_robot_contacts': self.robot_robot_contacts}


def summarise_runs(runs: Sequence[RunData], model: RobotModel = RobotModel()) -> BagSummary:
    """Summaries of every robot of a bag (robot-robot contacts need them all)."""
    tally = tally_runs(runs, model)
    figures = {f.name: f for f in tally.figures}
    several = len(runs) > 1
    summaries = []
    for run, motion in zip(runs, classify_recorded(runs, model)):
        trajectory = run.trajectory
        notes = [] if run.closed_properly else ['bag not closed properly: figures from its complete chunks']
        notes += [run.world_problem] if run.world_problem else []
        robot_collisions = None
        if run.world is not None and run.truth is not None:
            collisions, source = figures[run.name].world_contacts, 'world'
            robot_collisions = figures[run.name].robot_contacts if several else None
        elif run.truth is not None and run.odom is not None:
            collisions, source = contacts_from_slip(run.truth, run.odom), 'odom vs ground_truth'
        else:
            collisions, source = None, 'unknown'
            notes.append('collisions unknown: needs ground_truth and the world (or odom) topics')
        if several and run.truth is not None and robot_collisions is None:
            robot_collisions = figures[run.name].robot_contacts
        closest, sensor, when = None, None, None
        if run.ranges is not None:
            stamps, values, frames = run.ranges
            finite = np.flatnonzero(np.isfinite(values))
            if len(finite):
                best = finite[np.argmin(values[finite])]
                closest, sensor, when = float(values[best]), frames[best].decode(errors='replace'), float(stamps[best])
        distance = figures[run.name].distance if run.truth is not None else trajectory.distance
        duration = trajectory.duration
        summaries.append(RunSummary(
            bag=run.bag_path, namespace=run.namespace, trajectory_topic=trajectory.topic, motion=motion.kind,
            duration=duration, distance=distance, mean_speed=distance / duration if duration > 0 else 0.0,
            closest_approach=closest, closest_sensor=sensor, closest_time=when,
            collisions=collisions, collisions_from=source, robot_collisions=robot_collisions,
            straight=motion.straight, spin=motion.spin, circle=motion.circle, corners=motion.corners,
            closed_properly=run.closed_properly,
            final_pose=figures[run.name].final_pose if run.truth is not None else None, notes=notes))
    return BagSummary(runs[0].bag_path if runs else '', summaries,
                      tally.robot_robot_contacts if several else None, tally.contacts)


def summarise(run: RunData, model: RobotModel = RobotModel()) -> RunSummary:
    """One robot's summary (robot-robot contacts need `summarise_runs` over all robots)."""
    return summarise_runs([run], model).robots[0]
