"""`swarm_avoid_v0`: N e-pucks in one world, each a PettingZoo agent learning obstacle avoidance.

The robots touch and see each other (an ordinary `Simulation`, IR noise drawn by it); each agent's observation,
action and reward are those of `epuck_ros/Avoid-v0` (see `epuck_ros.envs.worlds`). `reset(seed=...)` places the
robots clear of everything and of each other (`place_robots`) and seeds the noise, both from the seed; episodes
are truncated together after `duration` simulated seconds, after which step() is refused until reset(). An action
for an agent the episode does not have is refused. `step()`'s infos hold, per agent, `contacts` (its contacts so far
in the episode, each counted once when it began: walls, obstacles and robots), `robot_contacts` (those with another
robot) and `touching` (whether it touches something now); `reset()`'s are empty, as Avoid-v0's. `render()` draws
every robot as Avoid-v0 draws its one (render_mode='rgb_array'; without it, a warning and None).
`parallel_env(robots=N)` is the parallel form, `env(robots=N)` the AEC form (agents acting in turn, the world
stepping once all have acted).
"""
from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv
from pettingzoo.utils.conversions import parallel_to_aec

from epuck_ros.envs.avoid import DEFAULT_DURATION, RENDER_FPS, action_space, observation_space, renders, world_of
from epuck_ros.envs.picture import Picture
from epuck_ros.envs.worlds import activations, check_actions, episode_steps, observations, step_rewards
from epuck_ros.model import RobotModel
from epuck_ros.simulation import Simulation
from epuck_ros.world import World, WorldError, place_robots

MAX_ROBOTS = 10000
"""Most robots in one swarm (the core's cost per robot stays flat up to there)."""


class SwarmAvoidEnv(ParallelEnv):
    """`robots` e-pucks named epuck0.. in `world` (default: the built-in 1 m arena with three boxes)."""

    metadata = {'name': 'swarm_avoid_v0', 'render_modes': ['rgb_array'], 'render_fps': RENDER_FPS,
                'is_parallelizable': True}

    def __init__(self, robots: int = 4, render_mode: str | None = None, world: World | str | Path | None = None,
                 duration: float = DEFAULT_DURATION, noise: bool = True) -> None:
        if isinstance(robots, bool) or not isinstance(robots, (int, np.integer)) or not 1 <= robots <= MAX_ROBOTS:
            raise ValueError(f'robots must be an integer from 1 to {MAX_ROBOTS}, got {robots!r}')
        if render_mode not in (None, *self.metadata['render_modes']):
            raise ValueError(f'render_mode must be None or rgb_array, got {render_mode!r}')
        self.episode_steps = episode_steps(duration, noise)
        self.render_mode, self.noise, self.model = render_mode, noise, RobotModel()
        self.world = world_of(world)
        self.possible_agents = [f'epuck{i}' for i in range(int(robots))]
        self.agents: list[str] = []
        self._observation_space, self._action_space = observation_space(), action_space()
        self._rng: np.random.Generator | None = None
        self.sim: Simulation | None = None
        self._steps = 0
        self._activation = np.zeros((int(robots), 8))
        self._picture = Picture(self.world, self.model)
        self._trail: list[np.ndarray] = []

    def observation_space(self, agent: str) -> spaces.Box:
        return self._observation_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._action_space

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[dict, dict]:
        if seed is not None or self._rng is None:
            self._rng = seeding.np_random(seed)[0]
        placement, noise = (int(value) for value in self._rng.integers(2 ** 63, size=2))
        try:
            world = place_robots(self.world, len(self.possible_agents), placement, self.model)
        except WorldError as error:
            raise ValueError(str(error)) from None
        self.sim = Simulation(world, self.model, seed=noise, noise=self.noise, cmd_timeout=0.0)
        self.agents = list(self.possible_agents)
        self._steps = 0
        self._trail = [self.sim.true_pose[:, :2].copy()]
        return self._observe(), {agent: {} for agent in self.agents}

    def step(self, actions: dict[str, np.ndarray]) -> tuple[dict, dict, dict, dict, dict]:
        if self.sim is None:
            raise RuntimeError('call reset() before step()')
        if not self.agents:
            raise RuntimeError('the episode has ended (every agent truncated): call reset() before step()')
        if not isinstance(actions, Mapping):
            raise ValueError(f'action rejected: expected a dict of actions by agent name, got {type(actions).__name__}')
        live = set(self.agents)
        unknown = [str(agent) for agent in actions if agent not in live]
        if unknown:
            raise ValueError(f'action rejected: no agent {", ".join(unknown[:5])} in this episode (agents '
                             f'{self.agents[0]}..{self.agents[-1]})')
        missing = [agent for agent in self.agents if agent not in actions]
        if missing:
            raise ValueError(f'action rejected: no action for {", ".join(missing)}')
        top = self.model.max_wheel_speed
        for index, agent in enumerate(self.possible_agents):
            if agent in live:
                left, right = check_actions(actions[agent], (2,)).tolist()
                self.sim.command_wheels(index, left * top, right * top)
        self.sim.step()
        self._steps += 1
        if self.render_mode is not None:
            self._trail.append(self.sim.true_pose[:, :2].copy())
        observation = self._observe()
        reward = step_rewards(self.sim, self._activation, self.model).tolist()
        ended = self._steps >= self.episode_steps
        agents = self.agents
        rewards = {agent: reward[int(agent[5:])] for agent in agents}
        self.agents = [] if ended else agents
        return (observation, rewards, {agent: False for agent in agents}, {agent: ended for agent in agents},
                self._infos(agents))

    def _infos(self, agents: list[str]) -> dict[str, dict[str, Any]]:
        """Each agent's contacts so far in the episode, those with robots among them, and whether it touches now."""
        sim = self.sim
        contacts, robots, touching = sim.collisions.tolist(), sim.robot_collisions.tolist(), sim.in_contact.tolist()
        return {agent: {'contacts': contacts[i], 'robot_contacts': robots[i], 'touching': touching[i]}
                for agent, i in ((agent, int(agent[5:])) for agent in agents)}

    def _observe(self) -> dict[str, np.ndarray]:
        self._activation = activations(self.sim.ir_raw, self.model)
        rows = observations(self._activation, self.sim.wheel_speeds, self.model)
        return {agent: rows[int(agent[5:])] for agent in self.agents}

    def render(self) -> np.ndarray | None:
        """The arena from above with every robot, its rays and its trail this episode, as Avoid-v0 draws one."""
        if not renders(self.render_mode, self.sim is not None):
            return None
        trails = np.stack(self._trail, axis=1)
        return self._picture.frame(self.sim.true_pose, self._activation, list(trails))

    def close(self) -> None:
        pass


def parallel_env(**kwargs: Any) -> SwarmAvoidEnv:
    return SwarmAvoidEnv(**kwargs)


def env(**kwargs: Any):
    """The AEC form: agents act in turn; the world steps once every agent has acted."""
    return parallel_to_aec(SwarmAvoidEnv(**kwargs))
