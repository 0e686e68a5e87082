"""Floor paint costs what it paints (issue 28, item 13): paint cheap to write was costly to draw.

Each polyline segment painted over the bounding box of its whole polyline (a 10,000-point line: 10,000 times the
box), a polygon looked at every edge for every texel of its box; a world's total paint work was not bounded; a
sweep read one world file once per `worlds:` entry. Now each segment costs its own box, a polygon its crossings,
the loader refuses paint whose work passes MAX_PAINT_WORK, and a spec reads each world once; the texture painted
is the same, texel for texel.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from epuck_ros.experiments import spec as spec_module
from epuck_ros.experiments.spec import load_spec
from epuck_ros.sensors import scene
from epuck_ros.sensors.scene import FloorTexture
from epuck_ros.world import WorldError, load_world
from epuck_ros.world import appearance
from epuck_ros.world.appearance import Paint


def reference_texture(arena_size, color, paint, max_texels=2048):
    """The floor as painted before the change, plainly: every texel of an item's box against every segment or
    edge of the item (the slow way, kept here as the definition)."""
    step = max(0.002, max(arena_size) / max_texels)
    half_x, half_y = arena_size[0] / 2.0, arena_size[1] / 2.0
    columns, rows = max(1, math.ceil(arena_size[0] / step)), max(1, math.ceil(arena_size[1] / step))
    image = np.empty((rows, columns, 3))
    image[:] = color
    for item in paint:
        points = np.array(item.points, dtype=float)
        reach = item.radius if item.kind == 'disc' else item.width / 2.0
        i0 = max(0, int(math.floor((points[:, 0].min() - reach + half_x) / step)))
        i1 = min(columns, int(math.ceil((points[:, 0].max() + reach + half_x) / step)) + 1)
        j0 = max(0, int(math.floor((points[:, 1].min() - reach + half_y) / step)))
        j1 = min(rows, int(math.ceil((points[:, 1].max() + reach + half_y) / step)) + 1)
        if i0 >= i1 or j0 >= j1:
            continue
        xs = (-half_x + (np.arange(i0, i1) + 0.5) * step)[None, :]
        ys = (-half_y + (np.arange(j0, j1) + 0.5) * step)[:, None]
        inside = np.zeros((j1 - j0, i1 - i0), dtype=bool)
        if item.kind == 'disc':
            inside = (xs - points[0, 0]) ** 2 + (ys - points[0, 1]) ** 2 <= item.radius ** 2
        elif item.kind == 'polygon':
            for (ax, ay), (bx, by) in zip(points, np.roll(points, -1, axis=0)):
                if ay != by:
                    inside ^= ((ay > ys) != (by > ys)) & (xs < ax + (ys - ay) * (bx - ax) / (by - ay))
        else:
            for (ax, ay), (bx, by) in zip(points[:-1], points[1:]):
                ex, ey = bx - ax, by - ay
                length2 = ex * ex + ey * ey
                along = np.clip(((xs - ax) * ex + (ys - ay) * ey) / length2, 0.0, 1.0) if length2 else 0.0
                inside |= (xs - ax - along * ex) ** 2 + (ys - ay - along * ey) ** 2 <= reach ** 2
        image[j0:j1, i0:i1][inside] = item.color
    return image


def random_paint(rng: np.random.Generator, half: float, items: int) -> tuple[Paint, ...]:
    """Polylines (with repeated points), polygons (self-crossing, with horizontal edges), discs, some off the floor."""
    paint = []
    for k in range(items):
        color = tuple(rng.uniform(0, 1, 3).round(3).tolist())
        count = int(rng.integers(2, 9))
        points = rng.uniform(-1.2 * half, 1.2 * half, (count, 2)).round(4)
        if k % 3 == 0:
            points[1] = points[0]   # a zero-length segment
            width = float(rng.uniform(0.005, 0.1))
            paint.append(Paint('polyline', tuple(map(tuple, points.tolist())), color, width=width))
        elif k % 3 == 1:
            points = np.vstack([points, [[points[0, 0] + 0.1, points[-1, 1]]]])   # a horizontal edge
            paint.append(Paint('polygon', tuple(map(tuple, points.tolist())), color))
        else:
            paint.append(Paint('disc', (tuple(points[0].tolist()),), color, radius=float(rng.uniform(0.01, 0.3))))
    return tuple(paint)


@pytest.mark.parametrize('arena, max_texels, seed', [((1.0, 1.0), 2048, 0), ((1.0, 0.6), 2048, 1),
                                                     ((20.0, 12.0), 256, 2), ((0.3, 0.3), 2048, 3)])
def test_the_floor_is_painted_texel_for_texel_as_before(arena, max_texels, seed):
    paint = random_paint(np.random.default_rng(seed), max(arena) / 2, 24)
    coarser = {'max_texels': max_texels} if max_texels != 2048 else {}   # a picture's texture
    new = FloorTexture(arena, (1.0, 1.0, 1.0), paint, **coarser).image
    assert np.array_equal(new, reference_texture(arena, (1.0, 1.0, 1.0), paint, max_texels))


def zigzag(points: int, half: float, ladder: bool = False) -> Paint:
    """A polyline from wall to wall and back, 2 cm wide: every segment's box is nearly the whole floor's width, as
    tall as the floor at random (or, a ladder, a few mm from one rung to the next)."""
    ys = np.linspace(-half, half, points) if ladder else np.random.default_rng(1).uniform(-half, half, points)
    return Paint('polyline', tuple((half * (1 if i % 2 else -1), float(y)) for i, y in enumerate(ys)), (0, 0, 0),
                 width=0.02)


def test_each_segment_costs_its_own_box(monkeypatch):
    """The texels the painting computes distances for (what np.clip sees) are those `paint_work` counts; before,
    each of 200 segments looked at the whole polyline's box (the floor: about 25 times as many here)."""
    seen = []
    clip = np.clip

    def counting_clip(values, *args, **kw):
        seen.append(np.size(values))
        return clip(values, *args, **kw)

    monkeypatch.setattr(np, 'clip', counting_clip)
    line = zigzag(200, 0.49, ladder=True)
    FloorTexture((1.0, 1.0), (1.0, 1.0, 1.0), (line,))
    box = 500 * 500   # the whole polyline's box: the floor
    assert sum(seen) <= appearance.paint_work((line,), (1.0, 1.0)) < 199 * box / 10, (sum(seen), 199 * box)


def world_text(size: float, paint_yaml: str) -> str:
    return f'arena: {{size: [{size}, {size}]}}\nfloor:\n  paint:\n{paint_yaml}'


def test_paint_too_costly_to_draw_is_refused_naming_the_field(tmp_path):
    line = zigzag(10000, 0.49)
    points = ', '.join(f'[{x:.4f}, {y:.4f}]' for x, y in line.points)
    path = tmp_path / 'zigzag.yaml'
    path.write_text(world_text(1.0, f'    - {{polyline: [{points}], width: 0.02, color: [0, 0, 0]}}\n'))
    with pytest.raises(WorldError, match=rf'zigzag.yaml: floor.paint: painting it would visit [\d,]+ floor texels of '
                                         rf'2 mm, more than {appearance.MAX_PAINT_WORK:,}'):
        load_world(path)
    discs = ''.join('    - {disc: [0, 0], radius: 10, color: [0, 0, 1]}\n' for _ in range(6))   # 6 whole floors
    path.write_text(world_text(20.0, discs))
    with pytest.raises(WorldError, match='floor.paint: painting it would visit'):
        load_world(path)


def test_the_shipped_worlds_are_far_within_the_bound():
    for name in ('line_track', 'lit_arena', 'coloured_objects'):
        world = load_world(f'{scene.__file__.rsplit("/", 2)[0]}/worlds/{name}.yaml')
        assert appearance.paint_work(world.appearance.paint, world.arena_size) < appearance.MAX_PAINT_WORK / 100


def test_a_spec_reads_each_world_file_once(tmp_path, monkeypatch):
    """A 100-entry `worlds:` list of one file read it 100 times (83 s for a 190 KB world)."""
    (tmp_path / 'arena.yaml').write_text('arena: {size: [1.5, 1.5]}\n')
    spec = tmp_path / 'spec.yaml'
    spec.write_text('controllers: [avoid]\nworlds: [' + ', '.join(['arena.yaml'] * 100 + ['default']) +
                    ']\nrobots: [1, 3]\nseeds: [0]\nduration: 1\n')
    reads = []
    monkeypatch.setattr(spec_module, 'load_world', lambda path: (reads.append(path), load_world(path))[1])
    trials = load_spec(spec).trials
    assert len(trials) == 101 * 2 and [Path(path) for path in reads] == [tmp_path / 'arena.yaml']
