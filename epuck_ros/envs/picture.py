"""What `render()` returns: the arena from above with its obstacles, each robot, its IR rays and its trail."""
from __future__ import annotations

import math

import numpy as np

from epuck_ros.model import RobotModel
from epuck_ros.world import World

PIXELS = 400
"""Width and height of a rendered frame."""


class Picture:
    """One matplotlib figure kept for every frame of an environment (made on the first frame: matplotlib loads only
    when something is rendered)."""

    def __init__(self, world: World, model: RobotModel) -> None:
        self.world, self.model = world, model
        self._figure = None

    def frame(self, poses: np.ndarray, activations: np.ndarray, trails: list[np.ndarray]) -> np.ndarray:
        """(PIXELS, PIXELS, 3) uint8: robots at `poses` (K, 3), rays coloured by `activations` (K, 8) in [0, 1],
        trails (K arrays of (T, 2) positions)."""
        from matplotlib.patches import Circle, Polygon, Rectangle
        if self._figure is None:
            from matplotlib.backends.backend_agg import FigureCanvasAgg
            from matplotlib.figure import Figure
            self._figure = Figure(figsize=(4, 4), dpi=PIXELS // 4)
            FigureCanvasAgg(self._figure)
            self._figure.subplots_adjust(0, 0, 1, 1)
        figure = self._figure
        figure.clear()
        axes = figure.add_axes((0, 0, 1, 1))
        half_x, half_y = (size / 2.0 for size in self.world.arena_size)
        margin = 0.03
        axes.set_xlim(-half_x - margin, half_x + margin)
        axes.set_ylim(-half_y - margin, half_y + margin)
        axes.set_aspect('equal')
        axes.axis('off')
        axes.add_patch(Rectangle((-half_x, -half_y), 2 * half_x, 2 * half_y, fill=False, lw=3, ec='0.3'))
        for box in self.world.boxes:
            c, s, a, b = math.cos(box.yaw), math.sin(box.yaw), box.size_x / 2, box.size_y / 2
            corners = [(box.x + c * u - s * v, box.y + s * u + c * v) for u, v in ((a, b), (-a, b), (-a, -b), (a, -b))]
            axes.add_patch(Polygon(corners, color='0.55'))
        for cylinder in self.world.cylinders:
            axes.add_patch(Circle((cylinder.x, cylinder.y), cylinder.radius, color='0.55'))
        sensors = np.asarray(self.model.sensor_poses)
        for (x, y, yaw), activation, trail in zip(poses.tolist(), activations, trails):
            if len(trail) > 1:
                axes.plot(trail[:, 0], trail[:, 1], color='tab:blue', lw=1, alpha=0.6)
            c, s = math.cos(yaw), math.sin(yaw)
            for (sx, sy, syaw), level in zip(sensors.tolist(), activation.tolist()):
                ox, oy = x + c * sx - s * sy, y + s * sx + c * sy
                reach = self.model.ir_range
                axes.plot([ox, ox + reach * math.cos(yaw + syaw)], [oy, oy + reach * math.sin(yaw + syaw)],
                          color=(min(1.0, 0.2 + level), 0.2, 0.2), lw=1)
            axes.add_patch(Circle((x, y), self.model.body_radius, color='tab:green', alpha=0.8))
            axes.plot([x, x + self.model.body_radius * c], [y, y + self.model.body_radius * s], color='k', lw=1.5)
        figure.canvas.draw()
        return np.asarray(figure.canvas.buffer_rgba())[:, :, :3].copy()
