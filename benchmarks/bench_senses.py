"""What the senses cost: the core with the camera on for one robot, frames per second per robot at 1, 50 and
1,000 robots, the other senses, and the sim node at real_time_factor 0 with the camera subscribed.

1. One robot roaming the lit arena (a light, floor paint, a box; bench_core's seeded commands): core steps/s IR
   only, then with the camera wanted (a 52 x 39 image rendered every step), the ground sensors, the light
   sensors, the IMU, and all of them; each a ratio to the IR-only figure measured in the same run.
2. Swarms (the coloured-objects world's look, 1 m x 1 m of arena per 50 robots, robots placed by seed): N robots
   all wanting the camera; one step renders N images. Printed: steps/s, frames/s per robot (= steps/s: every
   robot gets one image a step) and frames/s in total.
3. With --sim-node: the `sim` process on the coloured-objects world at real_time_factor 0, /clock counted for
   --seconds, first with nothing subscribed but /clock, then with a subscriber on camera/image_raw.

Run: python benchmarks/bench_senses.py [--steps N] [--counts 1,50,1000] [--sim-node] [--seconds S]
"""
from __future__ import annotations

import argparse
import math
import os
import time
from pathlib import Path

import numpy as np

from epuck_ros.simulation import Simulation
from epuck_ros.world import load_world, place_robots
from epuck_ros.world.data import World

WORLDS = Path(__file__).resolve().parents[1] / 'epuck_ros' / 'worlds'
COMMAND_PERIOD = 50
STEP = 0.032


def roam(world: World, kinds: tuple[str, ...], steps: int) -> tuple[float, float]:
    """Core steps/s of robot 0 roaming with `kinds` wanted: by wall clock and by process time (what the run cost
    this process, less what a loaded machine takes from it)."""
    sim = Simulation(world, seed=0)
    for kind in kinds:
        sim.senses.want(kind, [0])
    commands = np.random.default_rng(1).uniform(-0.3, 1.0, size=(steps // COMMAND_PERIOD + 1, 2)) * 6.28
    begin, begin_cpu = time.perf_counter(), time.process_time()
    for i in range(steps):
        if i % COMMAND_PERIOD == 0:
            sim.command_wheels(0, *commands[i // COMMAND_PERIOD])
        sim.step()
    return steps / (time.perf_counter() - begin), steps / (time.process_time() - begin_cpu)


def swarm_world(robots: int) -> World:
    """The coloured-objects world tiled to give every 50 robots a 1 m x 1 m cell, robots placed by seed."""
    cells = math.ceil(robots / 50)
    side = math.ceil(math.sqrt(cells))
    base = load_world(WORLDS / 'coloured_objects.yaml')
    world = World(arena_size=(float(side), float(side)), boxes=(), cylinders=(), appearance=base.appearance)
    return place_robots(world, robots, seed=0)


def swarm(robots: int, steps: int) -> float:
    world = swarm_world(robots)
    sim = Simulation(world, seed=0)
    sim.senses.want('camera', range(robots))
    for index in range(robots):
        sim.command_wheels(index, 3.0, 2.5)
    sim.step()
    begin = time.perf_counter()
    for _ in range(steps):
        sim.step()
    return steps / (time.perf_counter() - begin)


def sim_node(seconds: float) -> None:
    import subprocess
    import rclpy
    from rclpy.node import Node
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import Image

    world = str(WORLDS / 'coloured_objects.yaml')
    rclpy.init()
    try:
        for label, subscribe in (('IR only (nothing subscribed)', False), ('camera/image_raw subscribed', True)):
            sim = subprocess.Popen(['sim', '--ros-args', '-p', 'real_time_factor:=0', '-p', f'world:={world}'],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
            node = Node('bench_senses')
            clock: list[float] = []
            frames = [0]
            node.create_subscription(Clock, '/clock', lambda m: clock.append(m.clock.sec + 1e-9 * m.clock.nanosec),
                                     100)
            if subscribe:
                node.create_subscription(Image, 'camera/image_raw', lambda m: frames.__setitem__(0, frames[0] + 1),
                                         100)
            try:
                deadline = time.monotonic() + 60.0
                while len(clock) < 50 and time.monotonic() < deadline:
                    rclpy.spin_once(node, timeout_sec=0.1)
                while subscribe and not frames[0] and time.monotonic() < deadline:
                    rclpy.spin_once(node, timeout_sec=0.1)
                first, start, frames[0] = clock[-1], time.monotonic(), 0
                while time.monotonic() - start < seconds:
                    rclpy.spin_once(node, timeout_sec=0.1)
                wall = time.monotonic() - start
                rtf = (clock[-1] - first) / wall
                extra = f', {frames[0] / wall:,.0f} images/s received' if subscribe else ''
                print(f'sim node, 1 robot, {label:30s}: {rtf:7.1f}x real time = {rtf / STEP:7,.0f} steps/s{extra}')
            finally:
                node.destroy_node()
                sim.send_signal(2)
                sim.wait(15)
    finally:
        rclpy.try_shutdown()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--steps', type=int, default=5000, help='steps of the one-robot runs (default 5000)')
    parser.add_argument('--counts', default='1,50,1000', help='robot counts of the camera swarm runs')
    parser.add_argument('--sim-node', action='store_true', help='also measure the sim process')
    parser.add_argument('--seconds', type=float, default=10.0, help='wall seconds per sim node measurement')
    args = parser.parse_args()
    world = load_world(WORLDS / 'lit_arena.yaml')
    print(f'load average {os.getloadavg()[0]:.1f}; one robot roaming lit_arena.yaml, {args.steps} steps')
    ir_only, ir_only_cpu = roam(world, (), args.steps)
    print(f'  {"IR only":28s} {ir_only:9,.0f} steps/s (by process time {ir_only_cpu:9,.0f})')
    for label, kinds in (('camera', ('camera',)), ('ground sensors', ('ground',)), ('light sensors', ('light',)),
                         ('IMU', ('imu',)), ('all senses', ('camera', 'ground', 'light', 'imu'))):
        rate, rate_cpu = roam(world, kinds, args.steps)
        print(f'  {"+ " + label:28s} {rate:9,.0f} steps/s (by process time {rate_cpu:9,.0f}); '
              f'{rate / ir_only:.2f} of IR only')
    print('camera on for every robot (1 m x 1 m of arena per 50 robots):')
    for robots in (int(n) for n in args.counts.split(',')):
        steps = max(5, min(2000, 20000 // robots))
        rate = swarm(robots, steps)
        print(f'  {robots:5d} robots: {rate:9,.1f} steps/s = {rate:9,.1f} frames/s per robot, '
              f'{rate * robots:10,.0f} frames/s in all')
    if args.sim_node:
        sim_node(args.seconds)


if __name__ == '__main__':
    main()
