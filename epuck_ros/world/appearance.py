"""What a world looks like to the camera, the ground sensors and the light sensors: colours, heights, floor paint
and point lights. All optional: a world file without them means what it meant before (obstacles taller than
every sensor, a white floor, no light).

World-file keys (design.md, "Senses"):

    arena: {size: [1, 1], color: [r, g, b], height: 0.1}     # the walls; colours are 0..1
    boxes: [{position: ..., size: ..., color: [r, g, b], height: 0.1}]
    cylinders: [{position: ..., radius: ..., color: [r, g, b], height: 0.1}]
    floor: {color: [1, 1, 1], paint: [
        {polyline: [[x, y], ...], width: 0.02, color: [0, 0, 0]},
        {polygon: [[x, y], ...], color: [r, g, b]},
        {disc: [x, y], radius: 0.05, color: [r, g, b]}]}      # later items are painted over earlier ones
    lights: [{position: [x, y, z], intensity: 0.1}]

A light's irradiance at distance d (m) is intensity / d^2 (W/m^2), Webots' PointLight with attenuation 0 0 1:
Webots' default (1 0 0) has no fall-off, and the light sensors must tell near from far.

The floor is painted into a texture of `floor_step` texels (`epuck_ros.sensors.scene.FloorTexture`): each polyline
segment and disc costs the texels of its own bounding box, a polygon those of its bounding box and one look per
edge and texel row it spans. Paint is cheap to write and can be costly to draw (a zig-zag of long segments across
the arena), so a world is refused when painting its floor would visit more than MAX_PAINT_WORK texels in all.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol

Color = tuple[float, float, float]

WALL_COLOR: Color = (0.85, 0.85, 0.85)
BOX_COLOR: Color = (0.72, 0.53, 0.33)
CYLINDER_COLOR: Color = (0.6, 0.6, 0.65)
FLOOR_COLOR: Color = (1.0, 1.0, 1.0)
ROBOT_COLOR: Color = (0.45, 0.5, 0.45)
SKY_COLOR: Color = (0.62, 0.72, 0.85)
DEFAULT_HEIGHT = 0.1
"""m; Webots' RectangleArena wallHeight, and every obstacle's height unless the file says."""
MAX_PAINT_ITEMS = 1000
MAX_POINTS = 10000
"""Points in one polyline or polygon at most (a hostile file must stay cheap to paint)."""
MAX_LIGHTS = 64
FLOOR_RESOLUTION = 0.002
"""m per floor texel: a 1 m arena is 500 x 500 texels; a 2 cm line is 10 texels wide."""
MAX_TEXELS = 2048
"""Texels per side at most: a huge arena gets coarser texels rather than a huge texture."""
MAX_PAINT_WORK = 20_000_000
"""Texels the painting of one floor may visit in all (`paint_work`): a few seconds at most. The shipped worlds
need well under 1 % of it; a 1 m arena's whole floor is 250,000 texels."""


@dataclass(frozen=True)
class Paint:
    """One painted shape on the floor: a polyline `width` wide, a filled polygon, or a disc of `radius`."""

    kind: str   # 'polyline', 'polygon' or 'disc'
    points: tuple[tuple[float, float], ...]
    color: Color
    width: float = 0.0
    radius: float = 0.0


@dataclass(frozen=True)
class Light:
    """A point light at (x, y, z) m; irradiance intensity / d^2 at distance d."""

    x: float
    y: float
    z: float
    intensity: float


@dataclass(frozen=True)
class Appearance:
    """Colours and heights of the walls and of each box and cylinder (in the World's order), the floor, the lights."""

    wall_color: Color = WALL_COLOR
    wall_height: float = DEFAULT_HEIGHT
    box_colors: tuple[Color, ...] = ()
    box_heights: tuple[float, ...] = ()
    cylinder_colors: tuple[Color, ...] = ()
    cylinder_heights: tuple[float, ...] = ()
    floor_color: Color = FLOOR_COLOR
    paint: tuple[Paint, ...] = ()
    lights: tuple[Light, ...] = field(default=())

    def box_color(self, index: int) -> Color:
        return self.box_colors[index] if index < len(self.box_colors) else BOX_COLOR

    def box_height(self, index: int) -> float:
        return self.box_heights[index] if index < len(self.box_heights) else DEFAULT_HEIGHT

    def cylinder_color(self, index: int) -> Color:
        return self.cylinder_colors[index] if index < len(self.cylinder_colors) else CYLINDER_COLOR

    def cylinder_height(self, index: int) -> float:
        return self.cylinder_heights[index] if index < len(self.cylinder_heights) else DEFAULT_HEIGHT


ARENA_KEYS = ('color', 'height')
OBSTACLE_KEYS = ('color', 'height')
TOP_KEYS = ('floor', 'lights')
"""The keys this module adds to the world file (to the arena, to each box and cylinder, at the top)."""


def floor_step(arena_size: Sequence[float], max_texels: int = MAX_TEXELS) -> float:
    """The side (m) of a floor texel: FLOOR_RESOLUTION, or coarser so that no side has more than `max_texels`."""
    return max(FLOOR_RESOLUTION, max(arena_size) / max_texels)


def texel_span(low: float, high: float, half: float, step: float, count: int) -> tuple[int, int]:
    """The texels [first, last) along one axis of `count` whose centres may lie within [low, high] (the floor
    from -half, `step` per texel): one on either side more, never outside the floor."""
    return (max(0, int(math.floor((low + half) / step))),
            min(count, int(math.ceil((high + half) / step)) + 1))


def paint_work(paint: Sequence[Paint], arena_size: Sequence[float], max_texels: int = MAX_TEXELS) -> int:
    """The texels painting `paint` on this arena's floor visits (what FloorTexture's painting costs): each segment
    and disc its bounding box, each polygon its bounding box and the texel rows each edge spans."""
    step = floor_step(arena_size, max_texels)
    half_x, half_y = arena_size[0] / 2.0, arena_size[1] / 2.0
    columns, rows = max(1, math.ceil(arena_size[0] / step)), max(1, math.ceil(arena_size[1] / step))

    def box(xs: Sequence[float], ys: Sequence[float], reach: float) -> tuple[int, int]:
        i0, i1 = texel_span(min(xs) - reach, max(xs) + reach, half_x, step, columns)
        j0, j1 = texel_span(min(ys) - reach, max(ys) + reach, half_y, step, rows)
        return max(0, i1 - i0), max(0, j1 - j0)

    work = 0
    for item in paint:
        points = item.points
        if item.kind == 'polyline':
            for (ax, ay), (bx, by) in zip(points, points[1:]):
                width, height = box((ax, bx), (ay, by), item.width / 2.0)
                work += width * height
        elif item.kind == 'polygon':
            width, height = box([x for x, _ in points], [y for _, y in points], 0.0)
            edges = sum(box((ax, bx), (ay, by), 0.0)[1] for (ax, ay), (bx, by) in zip(points, points[1:] + points[:1]))
            work += width * height + edges
        else:
            width, height = box([points[0][0]], [points[0][1]], item.radius)
            work += width * height
    return work


class Fields(Protocol):
    """The world loader's field reader (every failure names the file and field)."""

    def fail(self, path: str, problem: str) -> Exception: ...

    def mapping(self, value: Any, path: str, keys: tuple[str, ...]) -> Mapping[str, Any]: ...

    def number(self, value: Any, path: str, positive: bool = False) -> float: ...

    def vector(self, value: Any, path: str, length: int, positive: bool = False) -> tuple[float, ...]: ...


def read_appearance(fields: Fields, top: Mapping[str, Any]) -> Appearance:
    """The appearance keys of a world file's top-level mapping, checked (the floor's paint against MAX_PAINT_WORK on
    its arena); the other keys are the loader's."""
    arena = top.get('arena') or {}
    arena_size = fields.vector(arena.get('size', [1.0, 1.0]), 'arena.size', 2, positive=True)
    boxes = _items(top, 'boxes')
    cylinders = _items(top, 'cylinders')
    floor = top.get('floor')
    floor = {} if floor is None else fields.mapping(floor, 'floor', ('color', 'paint'))
    return Appearance(
        wall_color=_color(fields, arena.get('color'), 'arena.color', WALL_COLOR),
        wall_height=_height(fields, arena.get('height'), 'arena.height'),
        box_colors=_trim([_color(fields, box.get('color'), f'boxes[{i}].color', BOX_COLOR)
                          for i, box in enumerate(boxes)], BOX_COLOR),
        box_heights=_trim([_height(fields, box.get('height'), f'boxes[{i}].height')
                           for i, box in enumerate(boxes)], DEFAULT_HEIGHT),
        cylinder_colors=_trim([_color(fields, c.get('color'), f'cylinders[{i}].color', CYLINDER_COLOR)
                               for i, c in enumerate(cylinders)], CYLINDER_COLOR),
        cylinder_heights=_trim([_height(fields, c.get('height'), f'cylinders[{i}].height')
                                for i, c in enumerate(cylinders)], DEFAULT_HEIGHT),
        floor_color=_color(fields, floor.get('color'), 'floor.color', FLOOR_COLOR),
        paint=_paint(fields, floor.get('paint'), arena_size),
        lights=_lights(fields, top.get('lights')))


def _trim(values: list[Any], default: Any) -> tuple[Any, ...]:
    """Without the trailing defaults: a world that sets none equals one built without an appearance."""
    while values and values[-1] == default:
        values.pop()
    return tuple(values)


def _items(top: Mapping[str, Any], name: str) -> list[Mapping[str, Any]]:
    """The loader has checked the list and its mappings already."""
    items = top.get(name)
    return [item for item in items if isinstance(item, Mapping)] if isinstance(items, list) else []


def _color(fields: Fields, value: Any, path: str, default: Color) -> Color:
    if value is None:
        return default
    color = fields.vector(value, path, 3)
    for i, channel in enumerate(color):
        if not 0.0 <= channel <= 1.0:
            raise fields.fail(f'{path}[{i}]', f'a colour channel is within 0..1, got {channel}')
    return color   # type: ignore[return-value]


def _height(fields: Fields, value: Any, path: str) -> float:
    return DEFAULT_HEIGHT if value is None else fields.number(value, path, positive=True)


def _list(fields: Fields, value: Any, path: str, most: int) -> list[Any]:
    if value is None:
        return []
    if not isinstance(value, list):
        raise fields.fail(path, f'expected a list, got {type(value).__name__}')
    if len(value) > most:
        raise fields.fail(path, f'at most {most} items, got {len(value)}')
    return value


def _points(fields: Fields, value: Any, path: str, least: int) -> tuple[tuple[float, float], ...]:
    points = _list(fields, value, path, MAX_POINTS)
    if len(points) < least:
        raise fields.fail(path, f'needs at least {least} points [x, y], got {len(points)}')
    return tuple(fields.vector(p, f'{path}[{i}]', 2) for i, p in enumerate(points))   # type: ignore[misc]


def _paint(fields: Fields, value: Any, arena_size: Sequence[float]) -> tuple[Paint, ...]:
    paint = []
    for i, item in enumerate(_list(fields, value, 'floor.paint', MAX_PAINT_ITEMS)):
        path = f'floor.paint[{i}]'
        item = fields.mapping(item, path, ('polyline', 'polygon', 'disc', 'width', 'radius', 'color'))
        kinds = [kind for kind in ('polyline', 'polygon', 'disc') if kind in item]
        if len(kinds) != 1:
            raise fields.fail(path, 'give exactly one of polyline, polygon, disc')
        kind = kinds[0]
        allowed = {'polyline': 'width', 'polygon': None, 'disc': 'radius'}[kind]
        for extra in ('width', 'radius'):
            if extra in item and extra != allowed:
                raise fields.fail(f'{path}.{extra}', f'a {kind} has no {extra}')
        color = _color(fields, item.get('color'), f'{path}.color', (0.0, 0.0, 0.0))
        if kind == 'disc':
            centre = fields.vector(item['disc'], f'{path}.disc', 2)
            radius = fields.number(_required(fields, item, 'radius', path), f'{path}.radius', positive=True)
            paint.append(Paint('disc', (centre,), color, radius=radius))   # type: ignore[arg-type]
        elif kind == 'polyline':
            width = fields.number(_required(fields, item, 'width', path), f'{path}.width', positive=True)
            paint.append(Paint('polyline', _points(fields, item['polyline'], f'{path}.polyline', 2), color,
                               width=width))
        else:
            paint.append(Paint('polygon', _points(fields, item['polygon'], f'{path}.polygon', 3), color))
    work = paint_work(paint, arena_size)
    if work > MAX_PAINT_WORK:
        raise fields.fail('floor.paint', f'painting it would visit {work:,} floor texels of '
                                         f'{floor_step(arena_size) * 1000:g} mm, more than {MAX_PAINT_WORK:,}: '
                                         'long segments across the arena cost their whole bounding box each '
                                         '(use fewer of them, or a polygon)')
    return tuple(paint)


def _required(fields: Fields, item: Mapping[str, Any], key: str, path: str) -> Any:
    if key not in item:
        raise fields.fail(f'{path}.{key}', 'missing')
    return item[key]


def _lights(fields: Fields, value: Any) -> tuple[Light, ...]:
    lights = []
    for i, item in enumerate(_list(fields, value, 'lights', MAX_LIGHTS)):
        path = f'lights[{i}]'
        item = fields.mapping(item, path, ('position', 'intensity'))
        x, y, z = fields.vector(_required(fields, item, 'position', path), f'{path}.position', 3)
        intensity = fields.number(item.get('intensity', 1.0), f'{path}.intensity')
        if intensity < 0.0:
            raise fields.fail(f'{path}.intensity', f'must not be negative, got {intensity}')
        lights.append(Light(x, y, z, intensity))
    return tuple(lights)


def appearance_dict(appearance: Appearance, data: dict[str, Any]) -> dict[str, Any]:
    """`data` (a world in the file format) with the appearance keys that differ from the defaults added, so a
    world without them writes exactly what it wrote before."""
    if appearance.wall_color != WALL_COLOR:
        data['arena']['color'] = list(appearance.wall_color)
    if appearance.wall_height != DEFAULT_HEIGHT:
        data['arena']['height'] = appearance.wall_height
    for name, color_of, height_of, default in (
            ('boxes', appearance.box_color, appearance.box_height, BOX_COLOR),
            ('cylinders', appearance.cylinder_color, appearance.cylinder_height, CYLINDER_COLOR)):
        for index, item in enumerate(data[name]):
            if color_of(index) != default:
                item['color'] = list(color_of(index))
            if height_of(index) != DEFAULT_HEIGHT:
                item['height'] = height_of(index)
    if appearance.floor_color != FLOOR_COLOR or appearance.paint:
        data['floor'] = {'color': list(appearance.floor_color), 'paint': [_paint_dict(p) for p in appearance.paint]}
    if appearance.lights:
        data['lights'] = [{'position': [light.x, light.y, light.z], 'intensity': light.intensity}
                          for light in appearance.lights]
    return data


def _paint_dict(paint: Paint) -> dict[str, Any]:
    shape: dict[str, Any]
    if paint.kind == 'disc':
        shape = {'disc': list(paint.points[0]), 'radius': paint.radius}
    elif paint.kind == 'polyline':
        shape = {'polyline': [list(p) for p in paint.points], 'width': paint.width}
    else:
        shape = {'polygon': [list(p) for p in paint.points]}
    return shape | {'color': list(paint.color)}
