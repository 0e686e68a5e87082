"""How fast the pure core steps one e-puck with its 8 IR rays in the default world (many robots: bench_swarm.py).

The robot roams: every 50 steps (1.6 s) it gets new forward-biased wheel speeds from a seeded generator, so it
crosses open floor, drives into walls and boxes, and slides along them, as a student's controller would.
Printed: steps per second, the factor over real time at the 32 ms step, and, measured in the same run on the
same machine, a naive baseline (forward Euler and a Python loop over rays and segments, no collisions, no
noise) to compare against. ir-sim, the closest pure-Python peer, reports about 3,800 steps/s (external figure,
not measured here).

Run: python benchmarks/bench_core.py [--steps N]
"""
from __future__ import annotations

import argparse
import bisect
import math
import os
import time

import numpy as np

from epuck_ros.model import IR_LOOKUP_TABLE, SENSOR_POSES, RobotModel
from epuck_ros.simulation import Simulation
from epuck_ros.world import default_world

IR_SIM_STEPS_PER_SECOND = 3800.0
COMMAND_PERIOD = 50


def wheel_commands(steps: int, seed: int = 1) -> np.ndarray:
    """(steps // COMMAND_PERIOD + 1, 2) forward-biased wheel speeds (rad/s)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-0.3, 1.0, size=(steps // COMMAND_PERIOD + 1, 2)) * RobotModel().max_wheel_speed


def run_core(steps: int) -> tuple[float, float, Simulation]:
    """(steps/s by wall clock, steps/s by process time, the simulation) for one robot roaming the default world."""
    sim = Simulation(default_world(), seed=0, noise=True, cmd_timeout=0.5)
    commands = wheel_commands(steps)
    begin, begin_cpu = time.perf_counter(), time.process_time()
    for i in range(steps):
        if i % COMMAND_PERIOD == 0:
            sim.command_wheels(0, *commands[i // COMMAND_PERIOD])
        sim.step()
    return steps / (time.perf_counter() - begin), steps / (time.process_time() - begin_cpu), sim


def run_naive(steps: int) -> float:
    """Forward Euler and a plain Python loop over 8 rays x every wall and box edge, as a first attempt would."""
    model, dt = RobotModel(), 0.032
    world = default_world()
    half_x, half_y = world.arena_size[0] / 2, world.arena_size[1] / 2
    polygons = [[(half_x, half_y), (-half_x, half_y), (-half_x, -half_y), (half_x, -half_y)]]
    for box in world.boxes:
        c, s, hx, hy = math.cos(box.yaw), math.sin(box.yaw), box.size_x / 2, box.size_y / 2
        polygons.append([(box.x + c * a - s * b, box.y + s * a + c * b)
                         for a, b in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))])
    segments = [(p[i], p[(i + 1) % len(p)]) for p in polygons for i in range(len(p))]
    distances, raws = list(IR_LOOKUP_TABLE[:, 0]), list(IR_LOOKUP_TABLE[:, 1])
    commands = wheel_commands(steps)
    x = y = yaw = 0.0
    begin = time.perf_counter()
    for i in range(steps):
        left, right = commands[i // COMMAND_PERIOD]
        v = model.wheel_radius * (left + right) / 2
        w = model.wheel_radius * (right - left) / model.wheel_separation
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        yaw += w * dt
        x = min(max(x, -half_x + model.body_radius), half_x - model.body_radius)
        y = min(max(y, -half_y + model.body_radius), half_y - model.body_radius)
        readings = []
        for sx, sy, syaw in SENSOR_POSES:
            ox = x + math.cos(yaw) * sx - math.sin(yaw) * sy
            oy = y + math.sin(yaw) * sx + math.cos(yaw) * sy
            dx, dy = math.cos(yaw + syaw), math.sin(yaw + syaw)
            nearest = math.inf
            for (ax, ay), (bx, by) in segments:
                ex, ey = bx - ax, by - ay
                denom = dx * ey - dy * ex
                if denom == 0.0:
                    continue
                s = ((ax - ox) * ey - (ay - oy) * ex) / denom
                t = ((ax - ox) * dy - (ay - oy) * dx) / denom
                if s >= 0.0 and 0.0 <= t <= 1.0:
                    nearest = min(nearest, s)
            k = min(max(bisect.bisect(distances, nearest), 1), len(distances) - 1)
            f = min((nearest - distances[k - 1]) / (distances[k] - distances[k - 1]), 1.0)
            readings.append(raws[k - 1] + f * (raws[k] - raws[k - 1]))
    return steps / (time.perf_counter() - begin)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--steps', type=int, default=20000)
    steps = parser.parse_args().steps
    run_core(500)  # warm-up: imports, caches, CPU frequency
    core, core_cpu, sim = run_core(steps)
    naive = run_naive(steps // 4)
    print(f'core: {core:,.0f} steps/s, {core * 0.032:,.0f}x real time at 32 ms '
          f'({steps} steps, {int(sim.collisions[0])} collisions, default world, 8 rays, noise on); '
          f'by process time {core_cpu:,.0f} steps/s (load average {os.getloadavg()[0]:.1f})')
    print(f'naive Euler + Python ray loop (same run): {naive:,.0f} steps/s -> core is {core / naive:.1f}x faster')
    print(f'ir-sim (external figure, not measured here): {IR_SIM_STEPS_PER_SECOND:,.0f} steps/s '
          f'-> core is {core / IR_SIM_STEPS_PER_SECOND:.1f}x')


if __name__ == '__main__':
    main()
