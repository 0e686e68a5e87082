"""`bag plot` tells the truth: fixed size, the whole arena at equal aspect, a short title, odometry from the
start pose, heading, contacts, start over end, a legend that names the coloured line, one colour per robot.

The picture is inspected through the matplotlib Figure `draw_runs` builds (its parts carry gids), and the
written files through their PNG size.
"""
from __future__ import annotations

import math
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
import yaml
from PIL import Image
from rclpy.serialization import serialize_message
from std_msgs.msg import String
from test_bag_cli import (MODEL, REPO, START_NS, SWARM_STARTS, WALL_X, drive, into_the_wall, odometry, write_run,
                          write_swarm)

from epuck_ros.bag.plot import draw_runs, plot_runs
from epuck_ros.bag.qos import QosProfile
from epuck_ros.bag.reader import Bag
from epuck_ros.bag.run_summary import load_runs, summarise_runs
from epuck_ros.bag.writer import BagWriter
from epuck_ros.world import world_from_dict


def figure_of(path: Path) -> plt.Figure:
    with Bag(path) as bag:
        runs = load_runs(bag)
    return draw_runs(runs, summarise_runs(runs))


def part(figure: plt.Figure, gid: str):
    found = [a for axes in figure.axes for a in [axes, *axes.get_children()] if a.get_gid() == gid]
    assert len(found) == 1, f'{gid}: {len(found)} found'
    return found[0]


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close('all')


def legend_texts(figure: plt.Figure) -> list[str]:
    return [text.get_text() for legend in figure.legends for text in legend.get_texts()]


@pytest.mark.parametrize('bag', ['avoid', 'circle', 'forward', 'rectangle', 'spin', 'swarm'])
def test_every_sample_bag_makes_a_1200_by_1000_picture_with_a_short_title(tmp_path, bag):
    output = tmp_path / f'{bag}.png'
    with Bag(REPO / 'bags' / bag) as opened:
        runs = load_runs(opened)
    plot_runs(runs, summarise_runs(runs), output)  # what `bag plot` does (its command line: test_bag_cli)
    assert Image.open(output).size == (1200, 1000)
    title = figure_of(REPO / 'bags' / bag)._suptitle.get_text().split('\n')
    assert len(title) <= 3 and max(len(line) for line in title) <= 90
    if bag == 'avoid':
        assert 'corner' not in ' '.join(title) and 'free motion' in title[0]


def test_a_non_square_arena_is_all_visible_at_equal_aspect(tmp_path):
    world = world_from_dict({'arena': {'size': [1.2, 0.3]}, 'robot': {'start': [-0.5, 0.0, 0.0]}})
    poses = [(x - 0.5, y, yaw) for x, y, yaw in drive([(0.5, 0.5, 8.0)])]
    figure = figure_of(write_run(tmp_path / 'corridor', poses, world=world))
    axes = part(figure, 'arena')
    (x0, x1), (y0, y1) = axes.get_xlim(), axes.get_ylim()
    assert x0 < -0.6 and x1 > 0.6 and y0 < -0.15 and y1 > 0.15
    assert axes.get_aspect() == 1.0
    figure.canvas.draw()
    box = axes.get_window_extent()
    assert box.width / box.height == pytest.approx((x1 - x0) / (y1 - y0), rel=0.01)
    figure.savefig(tmp_path / 'corridor.png')
    assert Image.open(tmp_path / 'corridor.png').size == (1200, 1000)


def test_odometry_is_drawn_in_the_world_from_the_start_pose(tmp_path):
    """Odometry starts at (0, 0, 0) at the start pose: redrawn from there it lies on the true path."""
    x0, y0, yaw0 = 0.2, -0.1, math.pi / 2
    world = world_from_dict({'robot': {'start': [x0, y0, yaw0]}})
    odom = drive([(0.5, 0.5, 3.0), (0.3, 0.6, 4.0)])
    truth = [(x0 + x * math.cos(yaw0) - y * math.sin(yaw0), y0 + x * math.sin(yaw0) + y * math.cos(yaw0), yaw0 + a)
             for x, y, a in odom]
    figure = figure_of(write_run(tmp_path / 'run', truth, odom, world=world))
    xs, ys = part(figure, 'odometry').get_data()
    assert xs == pytest.approx([p[0] for p in truth], abs=1e-12)
    assert ys == pytest.approx([p[1] for p in truth], abs=1e-12)


def test_a_spin_in_place_shows_its_heading():
    figure = figure_of(REPO / 'bags' / 'spin')
    heading = part(figure, 'heading')
    degrees = heading.get_lines()[0].get_ydata()
    assert abs(degrees[-1] - degrees[0]) > 500  # 1.5 turns
    arrows = next(c for c in part(figure, 'arena').get_children() if type(c).__name__ == 'Quiver')
    angles = np.degrees(np.arctan2(arrows.V, arrows.U)).round()
    assert len(set(angles.tolist())) >= 8  # arrows pointing all around the one spot


def test_contacts_are_marked_where_they_began(tmp_path):
    truth, odom = into_the_wall()
    figure = figure_of(write_run(tmp_path / 'wall', truth, odom))
    xs, ys = part(figure, 'contacts-world').get_data()
    assert list(xs) == pytest.approx([WALL_X] * 2, abs=0.002) and list(ys) == pytest.approx([0.0, 0.0])
    assert any(text.startswith('contacts with walls/obstacles (2)') for text in legend_texts(figure))


def test_the_start_is_drawn_over_the_end_of_a_closed_path_and_the_legend_names_the_colours():
    figure = figure_of(REPO / 'bags' / 'rectangle')
    start, end = part(figure, 'start'), part(figure, 'end')
    assert math.dist(start.get_xydata()[0], end.get_xydata()[0]) < MODEL.body_radius  # it came back
    assert start.get_zorder() > end.get_zorder() and start.get_marker() != end.get_marker()
    assert start.get_markersize() < end.get_markersize()  # the end shows around the start
    texts = legend_texts(figure)
    assert 'ground truth, colour = time (s)' in texts and 'start' in texts and 'end' in texts
    assert any(axes.get_ylabel() == 'time (s)' for axes in figure.axes)  # the colorbar


def test_each_robot_has_its_own_colour_and_a_long_list_stays_compact(tmp_path):
    figure = figure_of(write_swarm(tmp_path / 'three'))
    colours = [part(figure, f'trajectory /{name}').get_color() for name in SWARM_STARTS]
    assert len(set(map(str, colours))) == 3
    assert set(SWARM_STARTS) <= set(legend_texts(figure))
    assert any(t.startswith('contacts between robots, on both (2)') for t in legend_texts(figure))

    starts = {f'epuck{i}': (0.4 * math.cos(2 * math.pi * i / 30), 0.4 * math.sin(2 * math.pi * i / 30), 0.0)
              for i in range(30)}
    figure = figure_of(write_swarm(tmp_path / 'thirty', starts, {name: [0.0] * 5 for name in starts}))
    assert len(legend_texts(figure)) <= 4
    assert any(axes.get_ylabel() == 'robot' for axes in figure.axes)


def test_without_ground_truth_the_odometry_is_the_path_drawn_from_the_start_pose(tmp_path):
    x0, y0, yaw0 = 0.2, -0.1, math.pi / 2
    writer = BagWriter(tmp_path / 'odom_only')
    writer.add_topic('/world', 'std_msgs/msg/String', [QosProfile(depth=1, durability='transient_local')])
    writer.write('/world', serialize_message(String(data=f'robot: {{start: [{x0}, {y0}, {yaw0}]}}')), START_NS)
    writer.add_topic('/odom', 'nav_msgs/msg/Odometry', [QosProfile()])
    odom = drive([(0.5, 0.5, 2.0)])
    for step, pose in enumerate(odom):
        writer.write('/odom', odometry(pose, step, 'odom'), START_NS + step * 32_000_000)
    writer.close()
    figure = figure_of(tmp_path / 'odom_only')
    segments = part(figure, 'trajectory').get_segments()
    assert segments[0][0] == pytest.approx([x0, y0], abs=1e-12)
    assert segments[-1][1] == pytest.approx([x0, y0 + odom[-1][0]], abs=1e-12)  # driven along +y
    assert 'odometry (no ground truth), colour = time (s)' in legend_texts(figure)


def test_a_bag_without_a_world_says_the_arena_is_unknown():
    """Without a `world` topic no arena is drawn: the picture says so, and spans the path."""
    import dataclasses
    with Bag(REPO / 'bags' / 'spin') as bag:
        runs = [dataclasses.replace(run, world=None) for run in load_runs(bag)]
    figure = draw_runs(runs, summarise_runs(runs))
    notes = [text.get_text() for text in figure.findobj(match=lambda artist: artist.get_gid() == 'no-world')]
    assert notes == ['arena unknown: the bag has no world topic (the view spans the paths)']
    with Bag(REPO / 'bags' / 'spin') as bag:
        with_world = draw_runs(load_runs(bag), summarise_runs(load_runs(bag)))
    assert not with_world.findobj(match=lambda artist: artist.get_gid() == 'no-world')
    plt.close('all')


def test_a_step_published_twice_is_one_pose_of_the_run():
    """Lockstep sends an unanswered first step again: the bag then holds its stamp twice, the run once."""
    from epuck_ros.bag.runs import _trajectory
    rows = [(0, 0.0, 0.0, 0.0, 0.0, 0.0), (0, 0.0, 0.0, 0.0, 0.0, 0.0), (32_000_000, 0.001, 0.0, 0.0, 0.0, 0.0),
            (64_000_000, 0.002, 0.0, 0.0, 0.0, 0.0)]
    trajectory = _trajectory('/ground_truth', rows, 0)
    assert trajectory.t.tolist() == [0.0, 0.032, 0.064] and trajectory.x.tolist() == [0.0, 0.001, 0.002]


def test_the_floor_paint_and_the_lights_are_drawn(tmp_path):
    """The shipped line track with a light added: a pixel on the painted line is dark, the floor beside it stays
    light, the light's marker is gold."""
    world = yaml.safe_load((REPO / 'epuck_ros' / 'worlds' / 'line_track.yaml').read_text())
    world['lights'] = [{'position': [0.13, 0.07, 0.07], 'intensity': 0.5}]
    start = world['robot']['start']
    poses = [(start[0] + x, start[1] + y, yaw) for x, y, yaw in drive([(0.5, 0.5, 1.0)])]
    figure = figure_of(write_run(tmp_path / 'track', poses, world=world_from_dict(world)))
    figure.canvas.draw()
    pixels = np.asarray(figure.canvas.buffer_rgba())
    to_display = part(figure, 'arena').transData

    def rgb(x: float, y: float) -> np.ndarray:
        column, row = to_display.transform((x, y))
        return pixels[pixels.shape[0] - int(round(row)), int(round(column)), :3].astype(int)

    on_line, beside = rgb(-0.291, 0.1389), rgb(-0.22, 0.07)   # a vertex of the oval; 9 cm inside it
    assert on_line.max() < 128 and beside.min() > 240
    red, green, blue = rgb(0.13, 0.07)
    assert red > 200 and green > 150 and blue < 100   # gold
