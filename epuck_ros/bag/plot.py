"""``bag plot``: a picture of a run — the trajectory over the arena it was recorded in."""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use('Agg')  # files only: no display needed, works over ssh and in CI

import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

from epuck_ros.bag.run_summary import RunData, RunSummary  # noqa: E402
from epuck_ros.world import World  # noqa: E402

OBSTACLE_STYLE = {'facecolor': '0.6', 'edgecolor': '0.2'}


def _draw_world(axes: plt.Axes, world: World) -> None:
    width, height = world.arena_size
    axes.add_patch(Rectangle((-width / 2, -height / 2), width, height, fill=False, linewidth=3, edgecolor='0.2'))
    for box in world.boxes:
        axes.add_patch(Rectangle((box.x - box.size_x / 2, box.y - box.size_y / 2), box.size_x, box.size_y,
                                 angle=math.degrees(box.yaw), rotation_point='center', **OBSTACLE_STYLE))
    for cylinder in world.cylinders:
        axes.add_patch(Circle((cylinder.x, cylinder.y), cylinder.radius, **OBSTACLE_STYLE))


def _title(summary: RunSummary) -> str:
    first = (f'{summary.distance:.3f} m in {summary.duration:.1f} s '
             f'(mean {summary.mean_speed:.3f} m/s), collisions: '
             f'{"?" if summary.collisions is None else summary.collisions}')
    details = []
    if summary.closest_approach is not None:
        details.append(f'closest {summary.closest_approach:.3f} m')
    if summary.circle is not None:
        details.append(f'circle radius {summary.circle.radius:.4f} m')
    if summary.corners is not None:
        details.append('corners ' + ', '.join(f'{a:.0f}°' for a in summary.corners.angles_deg))
    robot = '' if summary.namespace == '/' else f' ({summary.namespace})'
    return f'{Path(summary.bag).name}{robot}\n{first}' + (f'\n{", ".join(details)}' if details else '')


def plot_run(run: RunData, summary: RunSummary, output: str | Path, body_radius: float = 0.037) -> None:
    """Write a PNG: world, odometry (dashed) if the truth is shown too, trajectory coloured by time."""
    figure, axes = plt.subplots(figsize=(7.5, 7))
    if run.world is not None:
        _draw_world(axes, run.world)
    if run.odom is not None and run.odom is not run.trajectory:
        axes.plot(run.odom.x, run.odom.y, '--', color='0.5', linewidth=1, label=f'{run.odom.topic} (odometry)')
    path = run.trajectory
    points = np.column_stack([path.x, path.y])
    lines = LineCollection(np.stack([points[:-1], points[1:]], axis=1), cmap='viridis', linewidth=2)
    lines.set_array(path.t[:-1])
    axes.add_collection(lines)
    figure.colorbar(lines, ax=axes, label='time (s)', shrink=0.8)
    axes.plot(path.x[0], path.y[0], 'o', color='tab:green', markersize=9, label='start')
    axes.plot(path.x[-1], path.y[-1], 's', color='tab:red', markersize=8, label='end')
    axes.add_patch(Circle((path.x[-1], path.y[-1]), body_radius, fill=False, edgecolor='tab:red'))
    axes.set_aspect('equal')
    axes.autoscale_view()
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.set_title(_title(summary), fontsize=10)
    axes.legend(loc='upper center', bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8, frameon=False)
    axes.grid(True, alpha=0.3)
    figure.savefig(output, dpi=120, bbox_inches='tight')
    plt.close(figure)
