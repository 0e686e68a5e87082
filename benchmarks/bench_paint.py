"""What floor paint costs to draw: the texture the senses and `bag plot` paint, at the bound a world may ask.

1. Painting the line track's floor (the shipped world with the most paint), and one whole 1 m floor (a disc
   covering it: 250,000 texels), the baseline.
2. A polyline zig-zagging from wall to wall of a 1 m arena with as many points as MAX_PAINT_WORK allows (each
   segment costs its bounding box: the worst paint a world may hold), and a polygon of 10,000 edges zig-zagging
   the same way (it costs its crossings, one per edge and row).
3. The same polyline in a 20 m arena (4 m: coarser texels, 2,048 a side), as `bag plot` paints it (1,024 a side).

Each is the best of --repeats, by process time, with its texels visited (`paint_work`) and the ratio to the
baseline's time per texel.

Run: python benchmarks/bench_paint.py [--repeats 3]
"""
from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np

from epuck_ros.bag.plot import FLOOR_TEXELS
from epuck_ros.sensors.scene import FloorTexture
from epuck_ros.world import load_world
from epuck_ros.world.appearance import MAX_PAINT_WORK, MAX_TEXELS, Paint, paint_work

WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'
WHITE, BLACK = (1.0, 1.0, 1.0), (0.0, 0.0, 0.0)


def zigzag(points: int, half: float, kind: str = 'polyline') -> Paint:
    """Wall to wall and back at random heights (seeded): every segment's box spans the floor's width."""
    ys = np.random.default_rng(1).uniform(-half, half, points)
    corners = tuple((half * (1 if i % 2 else -1), float(y)) for i, y in enumerate(ys))
    return Paint(kind, corners, BLACK, width=0.02 if kind == 'polyline' else 0.0)


def within_bound(half: float, arena: tuple[float, float]) -> Paint:
    """The longest such zig-zag whose work stays within MAX_PAINT_WORK."""
    low, high = 2, 10000
    while low < high:
        middle = (low + high + 1) // 2
        if paint_work((zigzag(middle, half),), arena) <= MAX_PAINT_WORK:
            low = middle
        else:
            high = middle - 1
    return zigzag(low, half)


def best_seconds(arena: tuple[float, float], paint: tuple[Paint, ...], repeats: int, texels: int) -> float:
    best = float('inf')
    for _ in range(repeats):
        began = time.process_time()
        FloorTexture(arena, WHITE, paint, texels)
        best = min(best, time.process_time() - began)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--repeats', type=int, default=3, help='best of this many runs (default 3)')
    repeats = parser.parse_args().repeats
    one_metre = (1.0, 1.0)
    track = load_world(WORLDS / 'line_track.yaml')
    floor = (Paint('disc', ((0.0, 0.0),), BLACK, radius=0.71),)
    cases = [('line_track.yaml floor', track.arena_size, track.appearance.paint, MAX_TEXELS),
             ('one whole 1 m floor (baseline)', one_metre, floor, MAX_TEXELS),
             ('polyline zig-zag at the bound, 1 m arena', one_metre, (within_bound(0.49, one_metre),), MAX_TEXELS),
             ('polygon zig-zag, 10,000 edges, 1 m arena', one_metre, (zigzag(10000, 0.49, 'polygon'),), MAX_TEXELS),
             ('polyline zig-zag at the bound, 20 m arena, as bag plot paints it', (20.0, 20.0),
              (within_bound(9.8, (20.0, 20.0)),), FLOOR_TEXELS)]
    print(f'best of {repeats} by process time   [load average {os.getloadavg()[0]:.1f}]')
    baseline = None
    for label, arena, paint, texels in cases:
        work = paint_work(paint, arena, texels)
        seconds = best_seconds(arena, paint, repeats, texels)
        per_texel = seconds / max(work, 1)
        if label.endswith('(baseline)'):
            baseline = per_texel
        ratio = f', {per_texel / baseline:.2f}x the baseline per texel' if baseline else ''
        points = sum(len(item.points) for item in paint)
        print(f'{label}: {points:,} points, {work:,} texels visited, {seconds:.3f} s{ratio}')


if __name__ == '__main__':
    main()
