"""`epuck_ros/Avoid-v0`: one e-puck learning obstacle avoidance, as one Gymnasium environment or N in one process.

Observation, action (an action beyond [-1, 1] is clipped to it) and reward: see `epuck_ros.envs.worlds`. `step()`'s
`info` holds `contacts`, the contacts with walls and obstacles so far in the episode (each counted once, when it
began), and `touching`, whether the body touches one now (what a fitness that judges time in contact needs); the
vector form gives each as an array with Gymnasium's mask (`_contacts`, `_touching`); `reset()`'s info is empty.
An episode starts at a random pose clear of every obstacle and is truncated after `duration` simulated seconds
(32 ms steps); it never terminates (a contact is not an end: the fitness already pays for it). The vector form
steps N worlds together in NumPy; as Gymnasium's own vector environments, `reset(seed=s)` seeds world i with s + i,
so world i replays a lone environment reset with seed s + i, and a world's next episode starts on the step after
its last (autoreset NEXT_STEP; all worlds end together).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import logger, spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from epuck_ros.envs.picture import Picture
from epuck_ros.envs.worlds import OBSERVATION_SIZE, Worlds, check_actions
from epuck_ros.world import World, default_world, load_world

DEFAULT_DURATION = 20.0
"""Simulated seconds per episode (625 steps)."""
RENDER_FPS = 31.25
"""Steps per simulated second (32 ms steps)."""
NO_RENDER_MODE = ('render() returns None: the environment was made without a render mode (make it with '
                  "render_mode='rgb_array' to get frames)")
"""What render() warns without a render mode (Gymnasium's own environments warn so too)."""


def renders(render_mode: str | None, started: bool) -> bool:
    """Whether render() draws a frame: with a render mode, after reset() (ResetNeeded before); without one it warns
    (`NO_RENDER_MODE`) and returns None, as Gymnasium's and PettingZoo's environments do."""
    if render_mode is None:
        logger.warn(NO_RENDER_MODE)
        return False
    if not started:
        raise gym.error.ResetNeeded('call reset() before render()')
    return True


def observation_space() -> spaces.Box:
    low = np.array([0.0] * 8 + [-1.0] * 2, dtype=np.float32)
    return spaces.Box(low, np.ones(OBSERVATION_SIZE, dtype=np.float32), dtype=np.float32)


def action_space() -> spaces.Box:
    return spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)


def world_of(world: World | str | Path | None) -> World:
    """The built-in world for None, a World as it is, a path loaded (WorldError names the file and field)."""
    if world is None:
        return default_world()
    return world if isinstance(world, World) else load_world(world)


class AvoidEnv(gym.Env):
    """One e-puck in the world (default: the built-in 1 m arena with three boxes)."""

    metadata = {'render_modes': ['rgb_array'], 'render_fps': RENDER_FPS}

    def __init__(self, render_mode: str | None = None, world: World | str | Path | None = None,
                 duration: float = DEFAULT_DURATION, noise: bool = True) -> None:
        if render_mode not in (None, *self.metadata['render_modes']):
            raise ValueError(f'render_mode must be None or rgb_array, got {render_mode!r}')
        self.render_mode = render_mode
        self._worlds = Worlds(1, world_of(world), duration, noise)
        self.observation_space, self.action_space = observation_space(), action_space()
        self._picture = Picture(self._worlds.world, self._worlds.model)
        self._trail: list[tuple[float, float]] = []

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        observation = self._worlds.reset([self.np_random])[0]
        self._trail = [tuple(self._worlds.sim.true_pose[0, :2].tolist())]
        return observation, {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        """One 32 ms step; info: `contacts` (with walls and obstacles so far this episode) and `touching` (now)."""
        if self._worlds.sim is None:
            raise gym.error.ResetNeeded('call reset() before step()')
        left, right = check_actions(action, (2,)).tolist()
        observation, reward, truncated = self._worlds.step_one(left, right)
        sim = self._worlds.sim
        if self.render_mode is not None:
            self._trail.append(tuple(sim.true_pose[0, :2].tolist()))
        return observation, reward, False, truncated, {'contacts': int(sim.collisions[0]),
                                                       'touching': bool(sim.in_contact[0])}

    def render(self) -> np.ndarray | None:
        """The arena from above (PIXELS x PIXELS rgb): the robot, its rays and its trail this episode."""
        if not renders(self.render_mode, self._worlds.sim is not None):
            return None
        return self._picture.frame(self._worlds.sim.true_pose, self._worlds.last_activation, [np.array(self._trail)])


class AvoidVectorEnv(VectorEnv):
    """`num_envs` independent Avoid worlds stepped together in one process."""

    metadata = {'render_modes': ['rgb_array'], 'render_fps': RENDER_FPS, 'autoreset_mode': AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, render_mode: str | None = None, world: World | str | Path | None = None,
                 duration: float = DEFAULT_DURATION, noise: bool = True) -> None:
        if render_mode not in (None, *self.metadata['render_modes']):
            raise ValueError(f'render_mode must be None or rgb_array, got {render_mode!r}')
        self._worlds = Worlds(num_envs, world_of(world), duration, noise)
        self.num_envs, self.render_mode = self._worlds.count, render_mode
        self.single_observation_space, self.single_action_space = observation_space(), action_space()
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._rngs: list[np.random.Generator] = []
        self._autoreset = False
        self._picture = Picture(self._worlds.world, self._worlds.model)
        self._trails: list[np.ndarray] = []

    def reset(self, *, seed: int | list[int | None] | None = None,
              options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        if seed is None and self._rngs:
            seeds = None   # every world goes on with its own generator, as a lone environment does
        elif seed is None or isinstance(seed, (int, np.integer)):
            seeds = [None if seed is None else int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f'reset: {len(seeds)} seeds for {self.num_envs} worlds')
        if seeds is not None:
            self._rngs = [seeding.np_random(s)[0] for s in seeds]
        self._autoreset = False
        return self._begin(), {}

    def _begin(self) -> np.ndarray:
        observation = self._worlds.reset(self._rngs)
        self._trails = [self._worlds.sim.true_pose[:, :2].copy()] if self.render_mode else []
        return observation

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        actions = check_actions(actions, (self.num_envs, 2))
        if not self._rngs:
            raise gym.error.ResetNeeded('call reset() before step()')
        ended = np.zeros(self.num_envs, dtype=bool)
        if self._autoreset:   # the step after the last: the new episodes' first observations, the actions unused
            self._autoreset = False
            return self._begin(), np.zeros(self.num_envs), ended, ended.copy(), self._info()
        observation, reward, truncated = self._worlds.step(actions)
        if self.render_mode:
            self._trails.append(self._worlds.sim.true_pose[:, :2].copy())
        self._autoreset = truncated
        return observation, reward, ended, np.full(self.num_envs, truncated), self._info()

    def _info(self) -> dict[str, np.ndarray]:
        """Each world's contacts so far in its episode and whether it touches something now (Gymnasium's vector form:
        values and a mask of the worlds that have one)."""
        sim, every = self._worlds.sim, np.ones(self.num_envs, dtype=bool)
        return {'contacts': sim.collisions.copy(), '_contacts': every, 'touching': sim.in_contact.copy(),
                '_touching': every}

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One frame per world, as the single environment draws it."""
        if not renders(self.render_mode, self._worlds.sim is not None):
            return None
        trails = np.stack(self._trails, axis=1)   # (worlds, steps, 2)
        poses, activation = self._worlds.sim.true_pose, self._worlds.last_activation
        return tuple(self._picture.frame(poses[i:i + 1], activation[i:i + 1], [trails[i]])
                     for i in range(self.num_envs))
