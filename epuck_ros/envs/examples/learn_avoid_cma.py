"""Learn obstacle avoidance on `epuck_ros/Avoid-v0` with CMA-ES (the `cma` package: pip install cma).

The policy is linear: wheel speeds = tanh(W observation + b), 22 weights. Each CMA-ES generation scores its
candidates together, one world each of the vector environment (all on the same seeded episode), and CMA-ES adapts
its search distribution from the ranking. At the end the learned policy drives fresh episodes it never saw, next to
random policies of the same form and a blind one driving straight ahead, and a picture of one of its runs is saved.

Run: python epuck_ros/envs/examples/learn_avoid_cma.py [--iterations N] [--popsize P] [--picture learned.png]
"""
from __future__ import annotations

import argparse

import cma
import gymnasium
import matplotlib.pyplot as plt
import numpy as np

import epuck_ros.envs  # noqa: F401  (registers epuck_ros/Avoid-v0)

AVOID = 'epuck_ros.envs:epuck_ros/Avoid-v0'
OBSERVATIONS, ACTIONS = 10, 2
WEIGHTS = ACTIONS * (OBSERVATIONS + 1)


def act(weights: np.ndarray, observations: np.ndarray) -> np.ndarray:
    """Actions (K, 2) of K linear policies `weights` (K, 22) for observations (K, 10)."""
    matrices = weights.reshape(-1, ACTIONS, OBSERVATIONS + 1)
    inputs = np.concatenate([observations, np.ones((len(observations), 1))], axis=1)
    return np.tanh(np.einsum('kai,ki->ka', matrices, inputs))


def episode_returns(weights: np.ndarray, seeds: list[int], duration: float) -> tuple[np.ndarray, np.ndarray]:
    """(mean reward per step, share of the steps touching a wall or an obstacle) of each policy (K, 22) on its
    seeded episode."""
    env = gymnasium.make_vec(AVOID, num_envs=len(weights), vectorization_mode='vector_entry_point',
                             duration=duration)
    observations, _ = env.reset(seed=seeds)
    total, touching, steps = np.zeros(len(weights)), np.zeros(len(weights)), 0
    while True:
        observations, rewards, _, truncated, info = env.step(act(weights, observations))
        total += rewards
        touching += info['touching']
        steps += 1
        if truncated.all():
            return total / steps, touching / steps


def learn(iterations: int, popsize: int, duration: float, seed: int) -> tuple[np.ndarray | None, list[float]]:
    """The best weights CMA-ES found (None if Ctrl-C came before the first generation ended), and the mean score of
    each generation; Ctrl-C ends the search early with what it found."""
    strategy = cma.CMAEvolutionStrategy(np.zeros(WEIGHTS), 0.5, {'popsize': popsize, 'seed': seed, 'verbose': -9})
    means = []
    try:
        for iteration in range(iterations):
            candidates = np.array(strategy.ask())
            scores, _ = episode_returns(candidates, [seed * 100000 + iteration] * popsize, duration)
            strategy.tell(list(candidates), list(-scores))   # cma minimises
            means.append(float(scores.mean()))
            print(f'iteration {iteration}: mean fitness {scores.mean():.3f}, best {scores.max():.3f}', flush=True)
    except KeyboardInterrupt:
        print(f'interrupted after {len(means)} iterations', flush=True)
    return (None if strategy.result.xbest is None else np.asarray(strategy.result.xbest)), means


def picture(weights: np.ndarray, path: str, seed: int) -> None:
    """The learned policy's run of 30 s on a fresh episode: arena, robot, rays and trail."""
    env = gymnasium.make(AVOID, render_mode='rgb_array', duration=30.0)
    observation, _ = env.reset(seed=seed)
    truncated = False
    while not truncated:
        observation, _, _, truncated, _ = env.step(act(weights[None], observation[None])[0].astype(np.float32))
    plt.imsave(path, env.render())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--iterations', type=int, default=30, help='CMA-ES generations (default 30)')
    parser.add_argument('--popsize', type=int, default=16, help='candidates per generation (default 16)')
    parser.add_argument('--duration', type=float, default=20.0, help='simulated seconds per episode (default 20)')
    parser.add_argument('--seed', type=int, default=1, help='seed of the search and the episodes (default 1)')
    parser.add_argument('--picture', help='save a picture of the learned policy driving (PNG)')
    args = parser.parse_args()
    best, _ = learn(args.iterations, args.popsize, args.duration, args.seed)
    if best is None:
        return
    tests = 20
    fresh = [10 ** 6 + k for k in range(tests)]   # episodes no generation was scored on
    straight = np.zeros(WEIGHTS)
    straight[OBSERVATIONS] = straight[2 * OBSERVATIONS + 1] = 3.0   # biases only: full speed ahead, blind
    rng = np.random.default_rng(args.seed)
    for name, policies in (('learned policy', np.tile(best, (tests, 1))),
                           ('random policies of its form', rng.normal(0.0, 0.5, (tests, WEIGHTS))),
                           ('straight ahead, blind', np.tile(straight, (tests, 1)))):
        scores, touching = episode_returns(policies, fresh, 60.0)
        print(f'{name:28} on {tests} fresh 60 s episodes: mean fitness {scores.mean():.3f}, '
              f'touching a wall or an obstacle {touching.mean():.1%} of the time')
    if args.picture:
        picture(best, args.picture, fresh[0])
        print(f'wrote {args.picture}')


if __name__ == '__main__':
    main()
