"""world_markers: every wall and obstacle of a World as a marker, checked against the World's own geometry."""
from __future__ import annotations

import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from visualization_msgs.msg import Marker, MarkerArray

from epuck_ros.markers import WALL_THICKNESS, world_markers
from epuck_ros.world import Box, Cylinder, World, default_world


def _by_ns(array: MarkerArray) -> dict[str, list[Marker]]:
    found: dict[str, list[Marker]] = {}
    for marker in array.markers:
        found.setdefault(marker.ns, []).append(marker)
    return found


def _yaw(marker: Marker) -> float:
    return 2.0 * math.atan2(marker.pose.orientation.z, marker.pose.orientation.w)


def _footprint_points(marker: Marker, inset: float) -> list[tuple[float, float]]:
    """Points `inset` inside (negative: outside) the marker's footprint edges, at each edge's middle."""
    x, y, yaw = marker.pose.position.x, marker.pose.position.y, _yaw(marker)
    if marker.type == Marker.CYLINDER:
        radius = marker.scale.x / 2.0 - inset
        return [(x + radius * math.cos(a), y + radius * math.sin(a)) for a in (0.0, 1.0, 2.5, 4.0)]
    half_x, half_y = marker.scale.x / 2.0 - inset, marker.scale.y / 2.0 - inset
    local = [(half_x, 0.0), (-half_x, 0.0), (0.0, half_y), (0.0, -half_y)]
    return [(x + math.cos(yaw) * lx - math.sin(yaw) * ly, y + math.sin(yaw) * lx + math.cos(yaw) * ly)
            for lx, ly in local]


WORLD = World(arena_size=(1.2, 0.8),
              boxes=(Box(-0.3, 0.2, 0.1, 0.05, 0.7), Box(0.3, -0.2, 0.2, 0.1)),
              cylinders=(Cylinder(0.0, 0.25, 0.04), Cylinder(0.4, 0.2, 0.06)))


def test_one_marker_per_wall_and_obstacle_in_the_world_frame() -> None:
    groups = _by_ns(world_markers(WORLD))
    assert {ns: len(markers) for ns, markers in groups.items()} == {'floor': 1, 'walls': 4, 'boxes': 2, 'cylinders': 2}
    for markers in groups.values():
        assert [m.id for m in markers] == list(range(len(markers)))
        for marker in markers:
            assert marker.header.frame_id == 'world'
            assert marker.action == Marker.ADD
            assert marker.color.a == 1.0
            assert marker.scale.z > 0.0
    assert all(m.type == Marker.CUBE for ns in ('floor', 'walls', 'boxes') for m in groups[ns])
    assert all(m.type == Marker.CYLINDER for m in groups['cylinders'])


@pytest.mark.parametrize('ns', ['boxes', 'cylinders'])
def test_obstacle_markers_cover_exactly_what_the_world_collides_with(ns: str) -> None:
    """Just inside a marker's footprint the World reports that obstacle; just outside, nothing."""
    for index, marker in enumerate(_by_ns(world_markers(WORLD))[ns]):
        for x, y in _footprint_points(marker, inset=1e-3):
            assert f'{ns}[{index}]' in WORLD.overlapping(x, y, 1e-4)
        for x, y in _footprint_points(marker, inset=-1e-3):
            assert WORLD.overlapping(x, y, 1e-4) == []


def test_walls_stand_outside_the_free_area() -> None:
    walls = _by_ns(world_markers(WORLD))['walls']
    width, height = WORLD.arena_size
    inner_faces = [walls[0].pose.position.x + WALL_THICKNESS / 2, walls[1].pose.position.y + WALL_THICKNESS / 2,
                   walls[2].pose.position.x - WALL_THICKNESS / 2, walls[3].pose.position.y - WALL_THICKNESS / 2]
    assert inner_faces == pytest.approx([-width / 2, -height / 2, width / 2, height / 2])
    # In the same arena without obstacles, a ray from the centre hits each wall's inner face.
    toward_walls = np.array([math.pi, -math.pi / 2, 0.0, math.pi / 2])
    distances = World(arena_size=WORLD.arena_size).cast_rays(np.zeros((4, 2)), toward_walls, max_range=10.0)
    assert list(distances) == pytest.approx([width / 2, height / 2, width / 2, height / 2])
    # The walls close the arena: each is long enough to reach the outer corners.
    assert walls[0].scale.y == walls[2].scale.y == pytest.approx(height + 2 * WALL_THICKNESS)
    assert walls[1].scale.x == walls[3].scale.x == pytest.approx(width + 2 * WALL_THICKNESS)


def test_ids_are_stable_and_the_array_survives_serialisation() -> None:
    first, second = world_markers(default_world()), world_markers(default_world())
    assert [(m.ns, m.id) for m in first.markers] == [(m.ns, m.id) for m in second.markers]
    decoded = deserialize_message(serialize_message(first), MarkerArray)
    assert [(m.ns, m.id, m.type, m.pose, m.scale) for m in decoded.markers] == \
        [(m.ns, m.id, m.type, m.pose, m.scale) for m in first.markers]


def test_an_empty_world_has_floor_and_walls_only() -> None:
    assert sorted(_by_ns(world_markers(World())).keys()) == ['floor', 'walls']
