"""The world as RViz2 / Foxglove markers: arena floor and walls, boxes and cylinders in frame `world`.

The simulator publishes `world_markers(world)` once, latched (transient local), so a viewer with `world` as
fixed frame sees the arena around each robot's `ground_truth`. Walls follow Webots' RectangleArena defaults
(`wallThickness` 0.01 m, `wallHeight` 0.1 m, standing outside the floor; shared/reference/epuck-model-sources.md):
the free area is exactly `arena_size`, as in `World`. Obstacles are drawn as tall as the walls (the model is
2-D: everything is taller than the IR rays). Each kind has its own namespace and ids count from 0 in file
order, so a re-published world replaces the same markers.
"""
from __future__ import annotations


from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from epuck_ros.conversions import quaternion_from_yaw
from epuck_ros.world import World

WORLD_FRAME = 'world'
WALL_THICKNESS = 0.01
"""m; RectangleArena wallThickness default."""
WALL_HEIGHT = 0.1
"""m; RectangleArena wallHeight default, also the height the obstacles are drawn with."""
FLOOR_THICKNESS = 0.001
"""m; a thin slab whose top is at z = 0."""

FLOOR_COLOUR = (0.85, 0.85, 0.8, 1.0)
WALL_COLOUR = (0.55, 0.57, 0.6, 1.0)
BOX_COLOUR = (0.72, 0.5, 0.3, 1.0)
CYLINDER_COLOUR = (0.3, 0.5, 0.72, 1.0)


def world_markers(world: World, frame_id: str = WORLD_FRAME) -> MarkerArray:
    """Floor (ns `floor`), four walls (ns `walls`: -x, -y, +x, +y), boxes (ns `boxes`), cylinders (ns `cylinders`)."""
    width, height = world.arena_size
    half_x, half_y = width / 2.0, height / 2.0
    offset = WALL_THICKNESS / 2.0
    outer_x, outer_y = width + 2 * WALL_THICKNESS, height + 2 * WALL_THICKNESS
    markers = [_marker(frame_id, 'floor', 0, Marker.CUBE, (0.0, 0.0, -FLOOR_THICKNESS / 2.0), 0.0,
                       (width, height, FLOOR_THICKNESS), FLOOR_COLOUR)]
    walls = (((-half_x - offset, 0.0), (WALL_THICKNESS, outer_y)), ((0.0, -half_y - offset), (outer_x, WALL_THICKNESS)),
             ((half_x + offset, 0.0), (WALL_THICKNESS, outer_y)), ((0.0, half_y + offset), (outer_x, WALL_THICKNESS)))
    for index, ((x, y), (size_x, size_y)) in enumerate(walls):
        markers.append(_marker(frame_id, 'walls', index, Marker.CUBE, (x, y, WALL_HEIGHT / 2.0), 0.0,
                               (size_x, size_y, WALL_HEIGHT), WALL_COLOUR))
    for index, box in enumerate(world.boxes):
        markers.append(_marker(frame_id, 'boxes', index, Marker.CUBE, (box.x, box.y, WALL_HEIGHT / 2.0), box.yaw,
                               (box.size_x, box.size_y, WALL_HEIGHT), BOX_COLOUR))
    for index, cylinder in enumerate(world.cylinders):
        diameter = 2.0 * cylinder.radius
        markers.append(_marker(frame_id, 'cylinders', index, Marker.CYLINDER,
                               (cylinder.x, cylinder.y, WALL_HEIGHT / 2.0), 0.0,
                               (diameter, diameter, WALL_HEIGHT), CYLINDER_COLOUR))
    return MarkerArray(markers=markers)


def _marker(frame_id: str, namespace: str, marker_id: int, shape: int, position: tuple[float, float, float],
            yaw: float, scale: tuple[float, float, float], colour: tuple[float, float, float, float]) -> Marker:
    """One ADD marker; stamp 0 (RViz uses the latest transform) and no lifetime (it stays until replaced)."""
    marker = Marker(ns=namespace, id=marker_id, type=shape, action=Marker.ADD)
    marker.header.frame_id = frame_id
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = (float(v) for v in position)
    marker.pose.orientation.z, marker.pose.orientation.w = quaternion_from_yaw(yaw)
    marker.scale.x, marker.scale.y, marker.scale.z = (float(v) for v in scale)
    marker.color = ColorRGBA(r=colour[0], g=colour[1], b=colour[2], a=colour[3])
    return marker
