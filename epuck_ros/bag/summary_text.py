"""The run's figures as text: `bag summary`'s lines and table, and the lines `bringup` prints at a run's end."""
from __future__ import annotations

import math
from collections.abc import Sequence

from epuck_ros.bag.run_summary import BagSummary, RunSummary
from epuck_ros.bag.shapes import Motion
from epuck_ros.bag.tally import RobotFigures


def contacts(count: int) -> str:
    """'1 contact', '2 contacts'."""
    return f'{count} contact' if count == 1 else f'{count} contacts'


def pose_text(pose: tuple[float, float, float] | None, digits: int = 3) -> str:
    """A final pose (x, y, yaw in radians) as the summaries print it."""
    if pose is None:
        return 'unknown (no ground truth)'
    x, y, yaw = pose
    return f'x {x:.{digits}f} m, y {y:.{digits}f} m, yaw {yaw:.{digits}f} rad ({math.degrees(yaw):.1f}°)'


def format_figures(figures: Sequence[RobotFigures], with_robots: bool | None = None) -> str:
    """One line per robot, as `bringup` prints its end-of-run summary: distance, contacts, where it ended."""
    with_robots = len(figures) > 1 if with_robots is None else with_robots
    lines = []
    for f in figures:
        robots = f', {f.robot_contacts} with robots' if with_robots else ''
        label = f'{f.name}: ' if f.name else ''
        lines.append(f'{label}{f.distance:.3f} m in {f.duration:.2f} s, '
                     f'{contacts(f.world_contacts)} with walls/obstacles{robots}; final pose {pose_text(f.final_pose)}')
    return '\n'.join(lines)


def turn_direction(rate: float) -> str:
    return 'counter-clockwise' if rate > 0 else 'clockwise'


def shape_lines(summary: RunSummary | Motion) -> list[tuple[str, str]]:
    """The figures of the run's shape, as (label, text): of a bag's summary, or of a Motion (`bringup`)."""
    if summary.straight is not None:
        s = summary.straight
        return [('Straight line', f'{s.length:.4f} m heading {s.heading_deg:.1f}°, '
                                  f'max deviation {s.max_deviation:.4f} m')]
    if summary.spin is not None:
        s = summary.spin
        return [('Heading rate', f'{math.degrees(s.heading_rate):.1f}°/s ({s.heading_rate:.3f} rad/s, '
                                 f'{turn_direction(s.heading_rate)}), {s.turns:.2f} turns')]
    if summary.circle is not None:
        c = summary.circle
        return [('Circle fit', f'radius {c.radius:.4f} m, centre ({c.centre[0]:.3f}, {c.centre[1]:.3f}), '
                               f'rms {c.rms_error:.4f} m, {c.laps:.2f} laps')]
    if summary.corners is not None:
        angles = ', '.join(f'{a:.1f}°' for a in summary.corners.angles_deg)
        sides = ', '.join(f'{s:.3f}' for s in summary.corners.side_lengths)
        return [('Corners', f'{len(summary.corners.angles_deg)}: {angles} (sides {sides} m)')]
    return []


def _collisions_text(summary: RunSummary) -> str:
    if summary.collisions is None:
        return 'unknown'
    robots = '' if summary.robot_collisions is None else f', {summary.robot_collisions} with robots'
    return f'{summary.collisions} with walls/obstacles{robots} (from {summary.collisions_from})'


def format_summary(summary: RunSummary) -> str:
    """One robot's summary as aligned text lines, in the style of ``ros2 bag info``."""
    lines = [('Bag', summary.bag), ('Robot', summary.namespace),
             ('Trajectory', summary.trajectory_topic),
             ('Motion', summary.motion),
             ('Duration', f'{summary.duration:.3f} s'),
             ('Distance', f'{summary.distance:.4f} m'),
             ('Mean speed', f'{summary.mean_speed:.4f} m/s')]
    if summary.closest_approach is None:
        lines.append(('Closest approach', 'nothing seen within IR range'))
    else:
        lines.append(('Closest approach', f'{summary.closest_approach:.4f} m '
                                          f'({summary.closest_sensor} at t={summary.closest_time:.2f} s)'))
    lines.append(('Collisions', _collisions_text(summary)))
    lines.append(('Final pose', pose_text(summary.final_pose, 4)))
    lines += shape_lines(summary)
    lines += [('Note', note) for note in summary.notes]
    return _aligned(lines)


def _aligned(lines: list[tuple[str, str]]) -> str:
    return '\n'.join(f'{label + ":":<19}{value}' for label, value in lines)


def format_bag_summary(summary: BagSummary) -> str:
    """One robot: its summary. Several: the bag's totals, then one table row per robot."""
    if len(summary.robots) == 1:
        return format_summary(summary.robots[0])
    robots = summary.robots
    world = [r.collisions for r in robots if r.collisions is not None]
    head = [('Bag', summary.bag), ('Robots', str(len(robots))),
            ('Duration', f'{max(r.duration for r in robots):.3f} s'),
            ('Distance', f'{sum(r.distance for r in robots):.4f} m in total'),
            ('Collisions', f'{sum(world)} with walls/obstacles (from {robots[0].collisions_from}), '
                           f'{summary.robot_robot_contacts} between robots (from ground_truth poses)')]
    notes = sorted({note for r in robots for note in r.notes})
    head += [('Note', note) for note in notes]
    header = ('robot', 'distance m', 'speed m/s', 'walls/obst.', 'robots', 'closest m', 'final x m', 'final y m',
              'final yaw rad', 'motion')
    rows = [(r.namespace, f'{r.distance:.4f}', f'{r.mean_speed:.4f}',
             '?' if r.collisions is None else str(r.collisions),
             '?' if r.robot_collisions is None else str(r.robot_collisions),
             '-' if r.closest_approach is None else f'{r.closest_approach:.4f}',
             *(('?',) * 3 if r.final_pose is None else (f'{value:.4f}' for value in r.final_pose)), r.motion)
            for r in robots]
    motion = len(header) - 1
    widths = [max(len(row[i]) for row in [header, *rows]) for i in range(len(header))]
    table = ['  '.join(cell.ljust(w) if i in (0, motion) else cell.rjust(w)
                       for i, (cell, w) in enumerate(zip(row, widths))).rstrip() for row in [header, *rows]]
    return _aligned(head) + '\n\n' + '\n'.join(table)
