"""How fast the learning environments step, against the bare core measured in the same run.

Printed, by process time (CPU seconds of this process, which other jobs on a shared machine change less than wall
time): the bare core's steps/s (bench_core's measure: one robot roaming the default world), one
`epuck_ros/Avoid-v0` environment driven by the same wheel speeds (goal: at least half the core's rate), the vector
environment with 1, 64, 1,024 and 8,192 worlds in env-steps/s (goal: 1,024 worlds at least 10x the single
environment), and with --evolve the wall time of `evolve` with the paper's population and generations on this
machine's cores (goal: under 5 minutes; the paper's run on the robot took days).

Run: python benchmarks/bench_envs.py [--seconds S] [--evolve]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gymnasium
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_core import COMMAND_PERIOD, run_core, wheel_commands  # noqa: E402

import epuck_ros.envs  # noqa: E402,F401
from epuck_ros.model import MAX_WHEEL_SPEED  # noqa: E402

AVOID = 'epuck_ros.envs:epuck_ros/Avoid-v0'
WORLDS = (1, 64, 1024, 8192)
PAPER_HOURS = 66.0
"""Floreano and Mondada (1994): the whole evolution on the real robot."""


def single_env(seconds: float) -> float:
    """Steps/s of one environment driven by bench_core's roaming wheel speeds (episodes reset as they end)."""
    env = gymnasium.make(AVOID)
    env.reset(seed=0)
    actions = (wheel_commands(100000) / MAX_WHEEL_SPEED).astype(np.float32)
    steps, begin = 0, time.process_time()
    while time.process_time() - begin < seconds:
        for _ in range(COMMAND_PERIOD):
            _, _, _, truncated, _ = env.step(actions[steps // COMMAND_PERIOD % len(actions)])
            steps += 1
            if truncated:
                env.reset()
    return steps / (time.process_time() - begin)


def vector_env(worlds: int, seconds: float) -> float:
    """Env-steps/s (worlds x steps) of the vector environment, each world on its own roaming wheel speeds."""
    env = gymnasium.make_vec(AVOID, num_envs=worlds, vectorization_mode='vector_entry_point')
    env.reset(seed=0)
    rng = np.random.default_rng(1)
    steps, begin = 0, time.process_time()
    while time.process_time() - begin < seconds:
        actions = rng.uniform(-0.3, 1.0, size=(worlds, 2)).astype(np.float32)
        for _ in range(COMMAND_PERIOD):
            env.step(actions)
            steps += 1
    return worlds * steps / (time.process_time() - begin)


def evolve_wall_time() -> float:
    """Wall seconds of `evolve` with the paper's population (80) and generations (100), one worker per core."""
    with tempfile.TemporaryDirectory() as out:
        begin = time.perf_counter()
        subprocess.run([str(Path(sys.executable).parent / 'evolve'), '-o', out, '--seed', '1'], check=True,
                       stderr=subprocess.DEVNULL)
        return time.perf_counter() - begin


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=3.0, help='wall seconds per measurement (default 3)')
    parser.add_argument('--evolve', action='store_true', help='also time evolve at the paper\'s size (~2 min)')
    seconds = parser.parse_args().seconds
    args = parser.parse_args()
    run_core(500)   # warm-up
    core = run_core(int(20000 * seconds / 3))[1]
    single = single_env(seconds)
    print('figures by process time (CPU seconds of this process: other jobs on the machine change them less)')
    print(f'bare core (bench_core): {core:,.0f} steps/s; one Avoid-v0 environment: {single:,.0f} steps/s '
          f'= {single / core:.0%} of the core (goal >= 50 %)   [load average {os.getloadavg()[0]:.1f}]')
    for worlds in WORLDS:
        rate = vector_env(worlds, seconds)
        print(f'vector environment, {worlds:>5} worlds: {rate:>10,.0f} env-steps/s = {rate / single:5.1f}x the single '
              f'environment' + ('   (goal >= 10x)' if worlds == 1024 else ''))
    if args.evolve:
        wall = evolve_wall_time()   # wall time: its Dask workers are other processes
        print(f'evolve, population 80 x 100 generations, {os.cpu_count()} cores: {wall:.0f} s wall (goal < 300 s); '
              f'the paper: about {PAPER_HOURS:.0f} hours on the robot ({PAPER_HOURS * 3600 / wall:,.0f}x)')


if __name__ == '__main__':
    main()
