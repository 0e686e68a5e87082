"""The README's learning example (CMA-ES on epuck_ros/Avoid-v0) learns on a tiny budget."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip('cma', reason='the learning example needs `pip install cma` (not a package dependency)')
EXAMPLE = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'envs' / 'examples' / 'learn_avoid_cma.py'


def load_example():
    spec = importlib.util.spec_from_file_location('learn_avoid_cma', EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_cma_es_learns_a_policy_that_beats_random_ones_on_unseen_episodes():
    example = load_example()
    best, means = example.learn(iterations=6, popsize=8, duration=3.0, seed=1)
    assert means[-1] > means[0]   # the search distribution moved to better policies
    fresh = [10 ** 6 + k for k in range(8)]
    learned, _ = example.episode_returns(np.tile(best, (8, 1)), fresh, 10.0)
    random, _ = example.episode_returns(np.random.default_rng(0).normal(0.0, 0.5, (8, example.WEIGHTS)), fresh, 10.0)
    assert learned.mean() > 2 * random.mean() and learned.mean() > 0.2, (learned, random)
