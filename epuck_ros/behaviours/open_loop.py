"""controller_2 (spin) and controller_3 (circle): constant wheel speeds, no sensing at all."""
from __future__ import annotations

from dataclasses import dataclass

from epuck_ros.behaviours.base import Behaviour, Config, Observation, WheelCommand, setting


@dataclass(frozen=True)
class OpenLoopConfig(Config):
    left: float = setting(0.5, 'left wheel speed, fraction of MAX_SPEED (6.28 rad/s)', -1.0, 1.0)
    right: float = setting(-0.5, 'right wheel speed, fraction of MAX_SPEED (6.28 rad/s)', -1.0, 1.0)


SPIN = OpenLoopConfig(left=0.5, right=-0.5)
"""controller_2: turns in place (clockwise) at R/L * 2 * 0.5 * 6.28 = 2.415 rad/s."""
CIRCLE = OpenLoopConfig(left=0.3, right=0.6)
"""controller_3: radius L/2 * (wR + wL) / (wR - wL) = 0.026 * 0.9 / 0.3 = 0.078 m, counter-clockwise."""


class OpenLoop(Behaviour):
    """The same wheel speeds every tick, from the first one."""

    def __init__(self, config: OpenLoopConfig) -> None:
        super().__init__()
        self.config = config
        self._command = WheelCommand.fractions(config.left, config.right)
        self.state = f'driving: left {config.left:+.2f}, right {config.right:+.2f} x MAX_SPEED'

    def control(self, obs: Observation) -> WheelCommand:
        return self._command
