"""The Gymnasium and PettingZoo environments, checked by the libraries' own checkers and against each other."""
from __future__ import annotations

import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import api_test, parallel_api_test, parallel_seed_test

import epuck_ros.envs  # noqa: F401  (registers epuck_ros/Avoid-v0)
from epuck_ros.envs import swarm_avoid_v0
from epuck_ros.envs.worlds import MAX_WORLDS, fitness
from epuck_ros.kinematics import wheels_from_twist
from epuck_ros.simulation import CommandError

AVOID = 'epuck_ros.envs:epuck_ros/Avoid-v0'


def test_gymnasium_check_env_passes_without_warnings():
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        env = gymnasium.make(AVOID, render_mode='rgb_array')
        check_env(env.unwrapped)
    assert [str(w.message) for w in caught] == []


def test_render_draws_the_arena_the_robot_and_its_trail():
    env = gymnasium.make(AVOID, render_mode='rgb_array')
    env.reset(seed=2)
    first = env.render()
    for _ in range(40):
        env.step(np.array([0.8, 0.6], dtype=np.float32))
    frame = env.render()
    assert frame.shape == (400, 400, 3) and frame.dtype == np.uint8
    assert (frame < 250).any() and not np.array_equal(first, frame)   # something drawn, and it moved


def rollout(env: gymnasium.Env, seed: int, steps: int) -> list[np.ndarray]:
    """Observations and rewards of `steps` seeded random actions after reset(seed)."""
    observation, _ = env.reset(seed=seed)
    actions = np.random.default_rng(seed).uniform(-1, 1, size=(steps, 2)).astype(np.float32)
    seen = [observation]
    for action in actions:
        observation, reward, terminated, truncated, _ = env.step(action)
        seen += [observation, np.array([reward, terminated, truncated])]
    return seen


def test_reset_with_a_seed_replays_the_episode_to_the_bit():
    first = rollout(gymnasium.make(AVOID), 7, 150)
    again = rollout(gymnasium.make(AVOID), 7, 150)
    other = rollout(gymnasium.make(AVOID), 8, 150)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    assert not np.array_equal(first[0], other[0])


@pytest.mark.parametrize('worlds', [1, 3])
def test_each_vector_world_is_the_single_environment_with_seed_plus_its_index(worlds):
    """Across an automatic reset too: a world's next episode is the lone environment's reset() without a seed."""
    steps, seed = 70, 11
    duration = 1.0   # 32 steps: the episode ends, and the step after it is the autoreset
    vector = gymnasium.make_vec(AVOID, num_envs=worlds, vectorization_mode='vector_entry_point', duration=duration)
    actions = np.random.default_rng(0).uniform(-1, 1, size=(steps, worlds, 2)).astype(np.float32)
    observations, _ = vector.reset(seed=seed)
    for i in range(worlds):
        single = gymnasium.make(AVOID, duration=duration)
        observation, _ = single.reset(seed=seed + i)
        assert np.array_equal(observation, observations[i])
    singles = [gymnasium.make(AVOID, duration=duration) for _ in range(worlds)]
    for i, single in enumerate(singles):
        single.reset(seed=seed + i)
    ended, resets = [False] * worlds, 0
    for step in range(steps):
        observation, reward, terminated, truncated, _ = vector.step(actions[step])
        for i, single in enumerate(singles):
            if ended[i]:
                expected, _ = single.reset()
                assert np.array_equal(observation[i], expected) and reward[i] == 0.0 and not truncated[i]
                ended[i] = False
                resets += 1
                continue
            expected, expected_reward, _, expected_truncated, _ = single.step(actions[step, i])
            assert np.array_equal(observation[i], expected), (step, i)
            assert reward[i] == expected_reward and truncated[i] == expected_truncated and not terminated[i]
            ended[i] = expected_truncated
    assert resets == 2 * worlds   # 32 steps, the reset, 32 steps, the reset, 4 steps


@pytest.mark.parametrize('action, problem', [
    (np.zeros(3), 'expected shape (2,)'),
    (np.array([np.nan, 0.0]), 'must be finite'),
    ('fast', 'expected wheel speeds'),
])
def test_a_bad_action_is_a_clear_error(action, problem):
    env = gymnasium.make(AVOID)
    env.reset(seed=0)
    with pytest.raises(CommandError, match=problem.replace('(', r'\(').replace(')', r'\)')):
        env.step(action)


def test_a_bad_vector_action_names_the_world():
    vector = gymnasium.make_vec(AVOID, num_envs=4, vectorization_mode='vector_entry_point')
    vector.reset(seed=0)
    actions = np.zeros((4, 2))
    actions[2, 1] = np.inf
    with pytest.raises(CommandError, match='in world 2'):
        vector.step(actions)
    with pytest.raises(CommandError, match=r'expected shape \(4, 2\)'):
        vector.step(np.zeros((3, 2)))


def test_an_unknown_task_is_a_clear_error():
    with pytest.raises(gymnasium.error.NameNotFound, match="Environment `Fly` doesn't exist"):
        gymnasium.make('epuck_ros.envs:epuck_ros/Fly-v0')


@pytest.mark.parametrize('count', [0, -1, MAX_WORLDS + 1, 10 ** 9])
def test_the_number_of_worlds_is_bounded_and_the_error_says_the_bound(count):
    with pytest.raises(ValueError, match=f'from 1 to {MAX_WORLDS}'):
        gymnasium.make_vec(AVOID, num_envs=count, vectorization_mode='vector_entry_point')


def test_pettingzoo_parallel_api_and_seed_tests_pass():
    parallel_api_test(swarm_avoid_v0.parallel_env(robots=3, duration=1.0), num_cycles=40)
    parallel_seed_test(lambda: swarm_avoid_v0.parallel_env(robots=3, duration=1.0))


def test_pettingzoo_aec_api_test_passes():
    api_test(swarm_avoid_v0.env(robots=3, duration=1.0), num_cycles=40)


def test_swarm_agents_end_together_and_the_robot_count_is_bounded():
    env = swarm_avoid_v0.parallel_env(robots=2, duration=0.64)
    observations, _ = env.reset(seed=1)
    assert set(observations) == {'epuck0', 'epuck1'}
    for _ in range(20):
        observations, rewards, terminations, truncations, _ = env.step({a: np.ones(2) for a in env.agents})
    assert all(truncations.values()) and env.agents == []
    with pytest.raises(ValueError, match='from 1 to 10000'):
        swarm_avoid_v0.parallel_env(robots=0)


def test_a_swarm_agent_pushing_into_a_wall_gets_the_avoid_reward():
    """Avoid-v0's reward counts the body's true motion: a blocked robot earns 0 however its motors turn."""
    env = swarm_avoid_v0.parallel_env(robots=1, duration=20.0, noise=False)
    env.reset(seed=3)
    model, blocked = env.model, []
    for _ in range(300):
        _, rewards, *_ = env.step({'epuck0': np.ones(2)})
        left, right = wheels_from_twist(env.sim.true_twist[:, 0], env.sim.true_twist[:, 1], model)
        avoid = fitness(np.column_stack([left, right]) / model.max_wheel_speed, env._activation)[0]
        assert rewards['epuck0'] == avoid
        if env.sim.in_contact[0] and not env.sim.true_twist[0].any():
            blocked.append(rewards['epuck0'])
    assert blocked and blocked == [0.0] * len(blocked), 'it drove into a corner and stayed there'


@pytest.mark.parametrize('make', [
    lambda **options: gymnasium.make(AVOID, **options),
    lambda **options: swarm_avoid_v0.parallel_env(robots=1, **options),
])
def test_a_bad_noise_or_duration_is_named_in_the_error(make):
    with pytest.raises(ValueError, match=r"^noise must be True or False, got 1$"):
        make(noise=1)
    with pytest.raises(ValueError, match=r"^duration must be a number of simulated seconds in \(0, 1e6\], got 0$"):
        make(duration=0)
