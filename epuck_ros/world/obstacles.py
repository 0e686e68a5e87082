"""The obstacles a world holds, boxes and cylinders: below both the World (`data`) and its prepared geometry
(`geometry`), which read them."""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Box:
    """A rectangular obstacle centred at (x, y), rotated by yaw (rad)."""

    x: float
    y: float
    size_x: float
    size_y: float
    yaw: float = 0.0

    def corners(self) -> list[tuple[float, float]]:
        """The four corners in the world frame, counter-clockwise from (+x, +y) in the box's own frame."""
        cos, sin = math.cos(self.yaw), math.sin(self.yaw)
        hx, hy = self.size_x / 2.0, self.size_y / 2.0
        return [(self.x + cos * lx - sin * ly, self.y + sin * lx + cos * ly)
                for lx, ly in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]


@dataclass(frozen=True)
class Cylinder:
    """A round obstacle centred at (x, y)."""

    x: float
    y: float
    radius: float
