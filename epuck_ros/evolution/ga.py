"""The simple generational genetic algorithm of the early evolutionary-robotics papers, written plainly.

Each generation: the best genome is kept as it is (elitism); the others are bred from parents drawn by
fitness-proportionate (roulette-wheel) selection, paired by one-point crossover with probability CROSSOVER, and
each of their weights is mutated with probability MUTATION by a normal step of MUTATION_STEP. Every draw comes from
one NumPy generator, in a fixed order, so a seed gives the same evolution on any machine.
"""
from __future__ import annotations

import numpy as np

CROSSOVER = 0.1
MUTATION = 0.2
MUTATION_STEP = 0.3
INITIAL_RANGE = 1.0
"""Initial weights are uniform in [-INITIAL_RANGE, INITIAL_RANGE]."""


def initial_population(rng: np.random.Generator, size: int, genes: int) -> np.ndarray:
    return rng.uniform(-INITIAL_RANGE, INITIAL_RANGE, size=(size, genes))


def next_generation(rng: np.random.Generator, population: np.ndarray, fitness: np.ndarray) -> np.ndarray:
    """The next population (same shape) bred from `population` (P, G) scored `fitness` (P,) (higher is better)."""
    size, genes = population.shape
    weights = np.maximum(fitness, 0.0)
    chances = weights / weights.sum() if weights.sum() > 0.0 else np.full(size, 1.0 / size)
    parents = population[rng.choice(size, size=(size - 1, 2), p=chances)]   # (P - 1, 2, G)
    children = parents[:, 0].copy()
    cross = rng.random(size - 1) < CROSSOVER
    points = rng.integers(1, genes, size=size - 1)
    tail = np.arange(genes)[None, :] >= points[:, None]
    children[cross[:, None] & tail] = parents[:, 1][cross[:, None] & tail]
    mutate = rng.random(children.shape) < MUTATION
    children += mutate * rng.normal(0.0, MUTATION_STEP, size=children.shape)
    return np.concatenate([population[[int(np.argmax(fitness))]], children])
