"""A population's fitness: each genome drives one world of the Avoid vector environment for one episode.

Every genome of a generation meets the same start pose and the same sensor noise (all its worlds are seeded with
the generation's seed), so genomes are compared on equal terms, and a genome's fitness does not depend on which
other genomes shared its batch: a population split over Dask workers scores exactly as in one process.
"""
from __future__ import annotations

import numpy as np

from epuck_ros.envs.avoid import AvoidVectorEnv
from epuck_ros.evolution.network import outputs


def evaluate(genomes: np.ndarray, seed: int, duration: float) -> np.ndarray:
    """(P,) fitness of the genomes (P, 22): the mean over the episode of each step's Floreano-Mondada fitness."""
    env = AvoidVectorEnv(num_envs=len(genomes), duration=duration)
    observation, _ = env.reset(seed=[seed] * len(genomes))
    previous = np.zeros((len(genomes), 2))
    total = np.zeros(len(genomes))
    steps = 0
    while True:
        previous = outputs(genomes, observation[:, :8].astype(float), previous)
        observation, reward, _, truncated, _ = env.step(previous)
        total += reward
        steps += 1
        if truncated.all():
            return total / steps
