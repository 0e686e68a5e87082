"""A population's fitness: each genome drives one episode in each of the evaluation worlds' starts, on the Avoid
vector environment; its fitness is the mean over them of Floreano and Mondada's per-step fitness.

Every genome of a generation meets the same start poses and the same sensor noise (episode k of a world is seeded
with the generation's seed + k, whoever drives it), so genomes are compared on equal terms, and a genome's fitness
does not depend on which other genomes shared its batch: a population split over Dask workers scores exactly as in
one process.

Why two worlds and two starts in each. One start says more about the start than about the genome: a 20 s episode
in the open 1 m arena meets a wall two or three times, a brief touch costs about a per cent of the episode, less
than the spread between starts (0.44 to 0.84 for one genome), and the best single score was a lucky start. And the
open arena alone rewards driving straight and always turning the same way at the last moment, touching now and
then (fitness 0.79 with 3.6 touches a minute, against 0.73 and none for turning away from whatever is seen): the
paper's robot lived in a looping corridor, where that habit keeps touching. Here each genome drives the default
arena and the corridor world (corridor.yaml), where turning away early scores best (0.64 against 0.42).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from epuck_ros.envs.avoid import AvoidVectorEnv
from epuck_ros.evolution.network import outputs
from epuck_ros.world import World, default_world, load_world

STARTS = 2
"""Episodes (start poses) in each world; a genome's fitness is the mean of its len(worlds()) * STARTS episodes."""
CORRIDOR = Path(__file__).resolve().parents[1] / 'worlds' / 'corridor.yaml'


def worlds() -> tuple[World, ...]:
    return default_world(), load_world(CORRIDOR)


def evaluate(genomes: np.ndarray, seed: int, duration: float) -> np.ndarray:
    """(P,) fitness of the genomes (P, 22): the mean over every world and start of each step's Floreano-Mondada
    fitness."""
    scores = [episodes(genomes, world, seed, duration) for world in worlds()]
    return np.mean(np.concatenate(scores, axis=1), axis=1)


def episodes(genomes: np.ndarray, world: World, seed: int, duration: float) -> np.ndarray:
    """(P, STARTS) mean step fitness of each genome in each of STARTS episodes in `world`."""
    drivers = np.repeat(genomes, STARTS, axis=0)   # genome p drives worlds p * STARTS + k
    env = AvoidVectorEnv(num_envs=len(drivers), world=world, duration=duration)
    observation, _ = env.reset(seed=[seed + k for _ in range(len(genomes)) for k in range(STARTS)])
    previous = np.zeros((len(drivers), 2))
    total = np.zeros(len(drivers))
    steps = 0
    while True:
        previous = outputs(drivers, observation[:, :8].astype(float), previous)
        observation, reward, _, truncated, _ = env.step(previous)
        total += reward
        steps += 1
        if truncated.all():
            return (total / steps).reshape(len(genomes), STARTS)
