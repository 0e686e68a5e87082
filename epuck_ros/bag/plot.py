"""``bag plot``: a picture of a run — every robot's path over the arena it was recorded in.

The image is always 1200 x 1000 px with the same layout, whatever the run: the arena fully visible at equal
aspect on the left (a corridor is wide and flat, a square is square), a short title, a legend below. One
robot: its true path coloured by time (colorbar), heading arrows along it, the odometry redrawn in the world
from the start pose (where its odom frame is), and the heading over time in a side panel (a spin in place
shows there). Several robots: one colour each. Contacts are marked where they began.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use('Agg')  # files only: no display needed, works over ssh and in CI

import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.colors import BoundaryNorm, ListedColormap  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

from epuck_ros.bag.run_summary import BagSummary, RunSummary  # noqa: E402
from epuck_ros.bag.runs import RunData, Trajectory  # noqa: E402
from epuck_ros.bag.summary_text import turn_direction  # noqa: E402
from epuck_ros.model import RobotModel  # noqa: E402
from epuck_ros.sensors.scene import FloorTexture  # noqa: E402
from epuck_ros.world import World  # noqa: E402
from epuck_ros.world.appearance import BOX_COLOR, CYLINDER_COLOR, FLOOR_COLOR, WALL_COLOR  # noqa: E402

FIGURE_INCHES = (10.0, 25.0 / 3.0)
DPI = 120
"""1200 x 1000 px."""
ARENA_BOX = (0.07, 0.16, 0.64, 0.72)
"""Figure fraction (left, bottom, width, height) the arena is drawn in, centred at equal aspect."""
COLORBAR_BOX = (0.77, 0.50, 0.022, 0.38)
SIDE_BOX = (0.77, 0.16, 0.20, 0.26)
ROBOT_SCALE_BOX = (0.77, 0.16, 0.022, 0.72)
HEADING_ARROWS = 16
"""Arrows along a one-robot path at most (a spin in place gets this many, spaced in time)."""
MAX_NAMED_ROBOTS = 12
"""Up to this many robots get a legend entry each; more share one colour scale labelled by name."""
MAX_LISTED_CORNERS = 6
OBSTACLE_STYLE = {'facecolor': '0.6', 'edgecolor': '0.2'}
TIME_COLORMAP = 'viridis'
FLOOR_TEXELS = 1024
"""Floor texels per side at most in a picture: the arena spans fewer pixels than that (the senses' texture can be
twice as fine, and four times the work to paint)."""


def _draw_world(axes: plt.Axes, world: World) -> None:
    """The arena, its painted floor and lights (when the world has them), obstacles in their colours (grey when
    the world gives none, as before colours existed)."""
    width, height = world.arena_size
    looks = world.appearance
    if looks.paint or looks.floor_color != FLOOR_COLOR:
        floor = FloorTexture(world.arena_size, looks.floor_color, looks.paint, FLOOR_TEXELS)
        axes.imshow(floor.image, origin='lower', extent=(-width / 2, width / 2, -height / 2, height / 2),
                    interpolation='nearest', alpha=0.6, zorder=0, gid='floor')
    axes.add_patch(Rectangle((-width / 2, -height / 2), width, height, fill=False, linewidth=3,
                             edgecolor=looks.wall_color if looks.wall_color != WALL_COLOR else '0.2'))
    for index, box in enumerate(world.boxes):
        color = looks.box_color(index)
        style = OBSTACLE_STYLE | ({'facecolor': color} if color != BOX_COLOR else {})
        axes.add_patch(Rectangle((box.x - box.size_x / 2, box.y - box.size_y / 2), box.size_x, box.size_y,
                                 angle=math.degrees(box.yaw), rotation_point='center', **style))
    for index, cylinder in enumerate(world.cylinders):
        color = looks.cylinder_color(index)
        style = OBSTACLE_STYLE | ({'facecolor': color} if color != CYLINDER_COLOR else {})
        axes.add_patch(Circle((cylinder.x, cylinder.y), cylinder.radius, **style))
    for light in looks.lights:
        axes.plot(light.x, light.y, marker='*', markersize=22, markerfacecolor='gold', markeredgecolor='0.3',
                  zorder=5, gid='light')


def _limits(world: World | None, paths: Sequence[Trajectory], body_radius: float) -> tuple[tuple, tuple]:
    """The arena (all of it) and every path, with a margin; at least 0.3 m across without a world."""
    xs = [v for p in paths for v in (float(p.x.min()), float(p.x.max()))]
    ys = [v for p in paths for v in (float(p.y.min()), float(p.y.max()))]
    if world is not None:
        half_w, half_h = world.arena_size[0] / 2, world.arena_size[1] / 2
        # odometry may drift far: never let it shrink the arena to a dot
        xs = [min(max(v, -3 * half_w), 3 * half_w) for v in xs] + [-half_w, half_w]
        ys = [min(max(v, -3 * half_h), 3 * half_h) for v in ys] + [-half_h, half_h]
    low_x, high_x = min(xs) - body_radius, max(xs) + body_radius
    low_y, high_y = min(ys) - body_radius, max(ys) + body_radius
    margin = 0.04 * max(high_x - low_x, high_y - low_y, 0.3)
    centre_x, centre_y = (low_x + high_x) / 2, (low_y + high_y) / 2
    half_x = max(high_x - low_x, 0.3) / 2 + margin
    half_y = max(high_y - low_y, 0.3) / 2 + margin
    return (centre_x - half_x, centre_x + half_x), (centre_y - half_y, centre_y + half_y)


def _shape_text(summary: RunSummary) -> str:
    if summary.straight is not None:
        return f'straight {summary.straight.length:.3f} m, max deviation {summary.straight.max_deviation:.4f} m'
    if summary.spin is not None:
        rate = summary.spin.heading_rate
        return f'{abs(math.degrees(rate)):.0f}°/s {turn_direction(rate)}, {summary.spin.turns:.2f} turns'
    if summary.circle is not None:
        return f'radius {summary.circle.radius:.4f} m, {summary.circle.laps:.2f} laps'
    if summary.corners is not None:
        angles = summary.corners.angles_deg
        listed = ', '.join(f'{a:.0f}°' for a in angles[:MAX_LISTED_CORNERS])
        return f'{len(angles)} corners: {listed}' + (', ...' if len(angles) > MAX_LISTED_CORNERS else '')
    return ''


def _title(summary: BagSummary) -> str:
    robots = summary.robots
    name = Path(summary.bag).name
    if len(robots) == 1:
        r = robots[0]
        robot = '' if r.namespace == '/' else f' {r.namespace}'
        contacts = '?' if r.collisions is None else r.collisions
        figures = (f'{r.distance:.3f} m in {r.duration:.1f} s (mean {r.mean_speed:.3f} m/s), '
                   f'collisions: {contacts}')
        if r.closest_approach is not None:
            figures += f', closest {r.closest_approach:.3f} m'
        shape = _shape_text(r)
        return f'{name}{robot}: {r.motion}\n{figures}' + (f'\n{shape}' if shape else '')
    walls = sum(r.collisions or 0 for r in robots)
    return (f'{name}: {len(robots)} robots\n{sum(r.distance for r in robots):.3f} m in all in '
            f'{max(r.duration for r in robots):.1f} s; contacts: {walls} with walls/obstacles, '
            f'{summary.robot_robot_contacts} between robots')


def _robot_colours(count: int) -> list:
    if count <= 10:
        return [plt.get_cmap('tab10')(i) for i in range(count)]
    if count <= 20:
        return [plt.get_cmap('tab20')(i) for i in range(count)]
    return [plt.get_cmap('turbo')(v) for v in np.linspace(0.05, 0.95, count)]


def _end_pose(axes: plt.Axes, path: Trajectory, colour: object, body_radius: float) -> None:
    """The body where the run ended, with a tick showing its heading."""
    x, y, yaw = float(path.x[-1]), float(path.y[-1]), float(path.yaw[-1])
    axes.add_patch(Circle((x, y), body_radius, fill=False, edgecolor=colour, linewidth=1.5, zorder=4))
    axes.plot([x, x + body_radius * math.cos(yaw)], [y, y + body_radius * math.sin(yaw)], color=colour,
              linewidth=1.5, zorder=4)


def _heading_arrows(axes: plt.Axes, path: Trajectory, length: float) -> None:
    """Arrows spaced along the path (5 arrow lengths apart at most 16), or in time when it turned on the spot."""
    travelled = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(path.x), np.diff(path.y)))])
    if travelled[-1] > 2 * length:  # smaller arrows on a small path (a circle of 0.078 m)
        extent = max(np.ptp(path.x), np.ptp(path.y))
        length = min(length, max(0.15 * extent, 0.4 * length))
        count = min(HEADING_ARROWS, max(2, int(travelled[-1] / (5 * length))))
        index = np.searchsorted(travelled, np.linspace(0.0, travelled[-1], count + 2)[1:-1])
    else:
        index = np.searchsorted(path.t, np.linspace(path.t[0], path.t[-1], HEADING_ARROWS + 2)[1:-1])
    index = index.clip(0, len(path.t) - 1)
    axes.quiver(path.x[index], path.y[index], np.cos(path.yaw[index]), np.sin(path.yaw[index]),
                angles='xy', scale_units='xy', scale=1.0 / length, width=0.005, headwidth=3.5, headlength=4.5,
                headaxislength=4, pivot='middle', color='0.1', zorder=5)


def _contacts(axes: plt.Axes, summary: BagSummary) -> list[Line2D]:
    handles = []
    for kind, marker, colour, label in (('world', 'X', 'tab:red', 'contacts with walls/obstacles'),
                                        ('robot', 'P', 'tab:orange', 'contacts between robots, on both')):
        points = [(c.x, c.y) for c in summary.contacts if c.kind == kind]
        count = len(points) // 2 if kind == 'robot' else len(points)
        if points:
            xs, ys = zip(*points)
            axes.plot(xs, ys, marker, color=colour, markeredgecolor='black', markersize=10, linestyle='none',
                      zorder=7, gid=f'contacts-{kind}')
            handles.append(Line2D([], [], marker=marker, color=colour, markeredgecolor='black', markersize=10,
                                  linestyle='none', label=f'{label} ({count})'))
    return handles


def _start_and_end_handles() -> list[Line2D]:
    return [Line2D([], [], marker='o', color='tab:green', markeredgecolor='white', markersize=9,
                   linestyle='none', label='start'),
            Line2D([], [], marker='s', color='tab:red', markersize=11, linestyle='none', label='end')]


def _plot_one(figure: plt.Figure, axes: plt.Axes, run: RunData, length: float, body_radius: float) -> list:
    path = run.path_in_world()
    handles = []
    odom = run.odom_in_world() if run.truth is not None else None
    if odom is not None:
        # over the true path (thin and dashed): where odometry agrees with the truth it would vanish under it
        axes.plot(odom.x, odom.y, '--', color='0.25', linewidth=1.0, zorder=4, gid='odometry')
        handles.append(Line2D([], [], linestyle='--', color='0.25', label='odometry, from the start pose'))
    points = np.column_stack([path.x, path.y])
    # round caps: butt-ended segments leave antialiasing seams that make the line look dotted
    lines = LineCollection(np.stack([points[:-1], points[1:]], axis=1), cmap=TIME_COLORMAP, linewidth=2.5,
                           capstyle='round', zorder=3)
    lines.set_array(path.t[:-1])
    lines.set_gid('trajectory')
    axes.add_collection(lines)
    figure.colorbar(lines, cax=figure.add_axes(COLORBAR_BOX), label='time (s)')
    what = 'ground truth' if path is run.truth else 'odometry (no ground truth)'
    handles.insert(0, Line2D([], [], color=plt.get_cmap(TIME_COLORMAP)(0.6), linewidth=2.5,
                             label=f'{what}, colour = time (s)'))
    _heading_arrows(axes, path, length)
    handles.append(Line2D([], [], marker=r'$\rightarrow$', color='0.15', markersize=14, linestyle='none',
                          label='heading'))
    axes.plot(path.x[-1], path.y[-1], 's', color='tab:red', markersize=11, zorder=6, gid='end')
    # the start over the end: on a closed path it stays visible
    axes.plot(path.x[0], path.y[0], 'o', color='tab:green', markeredgecolor='white', markersize=9, zorder=8,
              gid='start')
    _end_pose(axes, path, 'tab:red', body_radius)
    heading = figure.add_axes(SIDE_BOX, gid='heading')
    heading.plot(path.t, np.degrees(path.yaw), color='tab:blue', linewidth=1.5)
    heading.set_title('heading (°, unwrapped)', fontsize=10)
    heading.set_xlabel('time (s)', fontsize=9)
    heading.tick_params(labelsize=8)
    heading.grid(True, alpha=0.3)
    return handles + _start_and_end_handles()


def _plot_many(figure: plt.Figure, axes: plt.Axes, runs: Sequence[RunData], summary: BagSummary,
               body_radius: float) -> list:
    colours = _robot_colours(len(runs))
    handles = []
    for run, colour in zip(runs, colours):
        path = run.path_in_world()
        axes.plot(path.x, path.y, color=colour, linewidth=1.5, zorder=3, gid=f'trajectory {run.namespace}')
        axes.plot(path.x[0], path.y[0], 'o', color=colour, markeredgecolor='black', markersize=6, zorder=8)
        _end_pose(axes, path, colour, body_radius)
        if len(runs) <= MAX_NAMED_ROBOTS:
            handles.append(Line2D([], [], color=colour, linewidth=2, label=run.name or run.namespace))
    if len(runs) <= MAX_NAMED_ROBOTS:
        _figures_table(figure, summary)
    else:
        scale = plt.cm.ScalarMappable(norm=BoundaryNorm(np.arange(len(runs) + 1) - 0.5, len(runs)),
                                      cmap=ListedColormap(colours))
        bar = figure.colorbar(scale, cax=figure.add_axes(ROBOT_SCALE_BOX), label='robot')
        ticks = np.unique(np.linspace(0, len(runs) - 1, min(len(runs), 10)).round().astype(int))
        bar.set_ticks(ticks, labels=[runs[i].name for i in ticks])
        handles.append(Line2D([], [], color=colours[len(colours) // 2], linewidth=2,
                              label=f'{len(runs)} robots, one colour each (scale on the right)'))
    handles.append(Line2D([], [], marker='o', color='0.6', markeredgecolor='black', linestyle='none',
                          label='start'))
    handles.append(Line2D([], [], marker='o', fillstyle='none', color='0.3', markersize=11, linestyle='none',
                          label='end (body and heading)'))
    return handles


def _figures_table(figure: plt.Figure, summary: BagSummary) -> None:
    """Each robot's distance and contacts, in the right-hand column."""
    rows = ['contacts with', f'{"robot":<9}{"dist. m":>8}{"walls":>6}{"robots":>7}']
    for r in summary.robots:
        walls = '?' if r.collisions is None else r.collisions
        robots = '?' if r.robot_collisions is None else r.robot_collisions
        rows.append(f'{(r.namespace.rsplit("/", 1)[-1] or r.namespace)[:9]:<9}{r.distance:>8.3f}{walls:>6}{robots:>7}')
    rows[0] = rows[0].rjust(len(rows[1]))
    figure.text(0.745, COLORBAR_BOX[1] + COLORBAR_BOX[3], '\n'.join(rows), va='top', ha='left',
                family='monospace', fontsize=9)


def plot_runs(runs: Sequence[RunData], summary: BagSummary, output: str | Path,
              body_radius: float = RobotModel().body_radius) -> None:
    """Write the picture of a bag's robots (the format follows the output's extension)."""
    figure = draw_runs(runs, summary, body_radius)
    try:
        figure.savefig(output, dpi=DPI)
    finally:
        plt.close(figure)


def draw_runs(runs: Sequence[RunData], summary: BagSummary,
              body_radius: float = RobotModel().body_radius) -> plt.Figure:
    """The picture as a matplotlib Figure; its parts carry gids ('start', 'end', 'odometry', 'trajectory',
    'contacts-world', 'contacts-robot', 'heading') so they can be found again."""
    figure = plt.figure(figsize=FIGURE_INCHES, dpi=DPI)
    axes = figure.add_axes(ARENA_BOX, gid='arena')
    world = runs[0].world
    if world is not None:
        _draw_world(axes, world)
    else:
        axes.text(0.01, 0.99, 'arena unknown: the bag has no world topic (the view spans the paths)',
                  transform=axes.transAxes, ha='left', va='top', fontsize=9, color='0.35', gid='no-world')
    paths = [run.path_in_world() for run in runs]
    if len(runs) == 1:
        odom = runs[0].odom_in_world()
        paths += [odom] if odom is not None else []
    (x0, x1), (y0, y1) = _limits(world, paths, body_radius)
    if len(runs) == 1:
        handles = _plot_one(figure, axes, runs[0], 0.03 * max(x1 - x0, y1 - y0), body_radius)
    else:
        handles = _plot_many(figure, axes, runs, summary, body_radius)
    handles += _contacts(axes, summary)
    axes.set_xlim(x0, x1)
    axes.set_ylim(y0, y1)
    axes.set_aspect('equal', adjustable='box', anchor='C')
    axes.set_xlabel('x (m)')
    axes.set_ylabel('y (m)')
    axes.grid(True, alpha=0.3)
    figure.suptitle(_title(summary), fontsize=12, y=0.975, va='top')
    figure.legend(handles=handles, loc='lower center', bbox_to_anchor=(0.42, 0.005), ncol=min(len(handles), 4),
                  fontsize=9, frameon=False)
    return figure
