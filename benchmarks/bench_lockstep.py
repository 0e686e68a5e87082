"""Closed-loop speed in lockstep: the real `sim` and `avoid` processes at `real_time_factor` 0.

In lockstep the simulator steps only once every driven robot's controller answered the last step, so the
real-time factor reached is that of the whole loop (simulator, DDS both ways, controller). Measured, in the same
run, for the same simulated seconds (the simulator starts paused and pauses itself at `pause_at`):
- baseline: `avoid` reading the eight `proximity` Range messages of each step (what it did before `ir_raw`; forced
  here by remapping `ir_raw` away, as on a robot whose driver publishes no `ir_raw`);
- `avoid` reading `ir_raw`, one message per step (the issue's goal: >= 50x real time);
- N robots, all driven by one `avoid --robots all` process.
Printed per configuration: real-time factor, steps/s, robot-steps/s and the CPU each process used per step,
each the median of `--repeat` runs taken in turn. The speed is the loop's, from the first step to the last, with
nobody else on the loop: the bench reads `/clock` only until the first step, then asks the simulator every
END_POLL whether it paused itself at `pause_at` (the end is the middle of the last two looks). A reader of every
`/clock` (as this bench had) is one more process woken at each step: it cost the loop 10-20 % (alternating runs).
Before that, runs were timed from the resume, when the simulator's discovery window (up to 1 s from its start,
see sim_node.DISCOVERY_WINDOW) was often still running. The delay from the resume to the first step is printed
apart.

Run: . scripts/env.sh; ROS_DOMAIN_ID=43 python benchmarks/bench_lockstep.py [--seconds S] [--swarm N] [--repeat R]
"""
from __future__ import annotations

import argparse
import math
import os
import shutil
import statistics
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import rclpy
from rclpy.node import Node
from rclpy.parameter_client import AsyncParameterClient
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from epuck_ros.bringup.processes import interrupt
from measure import cpu_seconds, resume

STEP = 0.032
TIMEOUT = 60.0
POLL = 0.01
"""Wall seconds the bench node waits for a message at a time."""
END_POLL = 0.005
"""Wall seconds between two questions to the simulator whether it paused itself (the run's end)."""


def executable(name: str) -> str:
    return shutil.which(name) or str(Path(sys.executable).parent / name)


@dataclass
class Result:
    label: str
    robots: int
    rtf: float
    sim_cpu_us: float
    controller_cpu_us: float
    """CPU microseconds per step."""
    start_s: float
    """Wall seconds from the resume to the first step."""

    def line(self, baseline: Result | None) -> str:
        ratio = f'  {self.rtf / baseline.rtf:5.2f}x the baseline' if baseline else ''
        return (f'{self.label:<34} {self.robots:>3} robot(s) {self.rtf:7.1f}x real time = {self.rtf / STEP:7,.0f} '
                f'steps/s = {self.rtf / STEP * self.robots:8,.0f} robot-steps/s; CPU per step: sim '
                f'{self.sim_cpu_us:6.0f} us, avoid {self.controller_cpu_us:6.0f} us; first step {self.start_s:4.2f} s '
                f'after the resume{ratio}')


def wait(node: Node, condition: object, what: str, timeout: float = TIMEOUT) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit(f'bench_lockstep: timed out waiting for {what}')
        rclpy.spin_once(node, timeout_sec=POLL)


def paused_at(node: Node, params: AsyncParameterClient) -> float:
    """Wall time at which the simulator paused itself (pause_at), within END_POLL: the middle of the last look that
    saw it running and the first that saw it paused."""
    deadline = time.monotonic() + TIMEOUT * 10
    running_seen = time.monotonic()
    while time.monotonic() < deadline:
        asked = time.monotonic()
        future = params.get_parameters(['paused'])
        wait(node, future.done, 'the sim to answer whether it paused')
        if future.result().values[0].bool_value:
            return (running_seen + asked) / 2
        running_seen = asked
        time.sleep(END_POLL)
    raise SystemExit('bench_lockstep: timed out waiting for the end of the run')


def run(node: Node, label: str, seconds: float, robots: int, ir_raw: bool) -> Result:
    """One closed-loop run of `seconds` simulated seconds; the processes are stopped before returning."""
    sim = subprocess.Popen([executable('sim'), '--ros-args', '-p', 'lockstep:=true', '-p', 'real_time_factor:=0',
                            '-p', 'paused:=true', '-p', f'pause_at:={seconds}', '-p', f'robots:={robots}'],
                           stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    avoid = subprocess.Popen([executable('avoid'), *(['--robots', 'all'] if robots > 1 else []), '--ros-args',
                              '-p', 'use_sim_time:=true', *([] if ir_raw else ['-r', 'ir_raw:=ir_raw_unused'])],
                             stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    try:
        names = [f'/epuck{i}/' for i in range(robots)] if robots > 1 else ['/']
        reads = 'ir_raw' if ir_raw else 'proximity'
        wait(node, lambda: all(node.count_publishers(f'{n}wheel_cmd') and node.count_subscribers(f'{n}{reads}')
                               for n in names), f'avoid to drive every robot and read {reads}')
        params = AsyncParameterClient(node, 'sim')
        wait(node, params.services_are_ready, 'the sim parameter services')
        first: list[tuple[float, float]] = []  # (wall, simulated) time of the first /clock
        clock = node.create_subscription(Clock, '/clock', lambda msg: first.append(
            (time.monotonic(), msg.clock.sec + msg.clock.nanosec * 1e-9)),
            QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        wait(node, lambda: clock.get_publisher_count() > 0, 'the sim\'s /clock')
        cpu = (cpu_seconds(sim.pid), cpu_seconds(avoid.pid))
        resumed = time.monotonic()
        if not resume(params, lambda future, timeout: rclpy.spin_until_future_complete(node, future,
                                                                                       timeout_sec=timeout)):
            raise SystemExit('bench_lockstep: the sim did not answer the resume')
        wait(node, lambda: bool(first), 'the first step')
        node.destroy_subscription(clock)
        wall0, sim0 = first[0]
        ended = paused_at(node, params)
        steps = math.ceil(seconds / STEP - 1e-9)  # the sim pauses on the first step at or after `seconds`
        sim_cpu, avoid_cpu = (cpu_seconds(p.pid) - before for p, before in zip((sim, avoid), cpu))
        return Result(label, robots, (steps * STEP - sim0) / (ended - wall0), sim_cpu / steps * 1e6,
                      avoid_cpu / steps * 1e6, wall0 - resumed)
    finally:
        for process in (avoid, sim):
            interrupt(process, 15)


def median(runs: list[Result]) -> Result:
    """Field by field median of runs of one configuration."""
    first = runs[0]
    return Result(first.label, first.robots, statistics.median(r.rtf for r in runs),
                  statistics.median(r.sim_cpu_us for r in runs), statistics.median(r.controller_cpu_us for r in runs),
                  statistics.median(r.start_s for r in runs))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=30.0, help='simulated seconds per run (default 30)')
    parser.add_argument('--swarm', type=int, default=10, help='robots of the one-process run (default 10; 0 = skip)')
    parser.add_argument('--repeat', type=int, default=3, help='runs of each configuration, in turn (default 3)')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    rclpy.init()
    node = rclpy.create_node('bench_lockstep')
    configurations = [('avoid on 8 proximity Ranges/step', 1, False), ('avoid on 1 ir_raw/step', 1, True)]
    if args.swarm > 1:
        configurations.append(('avoid --robots all, ir_raw', args.swarm, True))
    try:
        results: dict[str, list[Result]] = {label: [] for label, _, _ in configurations}
        for _ in range(args.repeat):
            for label, robots, ir_raw in configurations:
                results[label].append(run(node, label, args.seconds, robots, ir_raw))
        medians = [median(runs) for runs in results.values()]
        for result in medians:
            print(result.line(None if result is medians[0] else medians[0]), flush=True)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
