"""Does the live view slow the simulator down? The `sim` node at `real_time_factor` 0: alone, with the `view` node
running and no page open (as `bringup --view` before a browser connects), and with a page connected.

One `sim` process (default world, noise on) runs throughout and the three phases alternate. The page is a client
reading the view's event stream (`/events?robot=epuck`) as a browser does. Per phase:
- the real-time factor reached: simulated time (/clock, read by a best-effort depth-1 subscription sampled only
  at the start and end of the phase, so measuring costs the sim nothing) over wall time;
- the sim's CPU time per simulated second (Linux /proc): what each step costs the sim whatever else the machine
  runs. Its inverse is the real-time factor the sim would reach with a core to itself, a figure other jobs on
  the machine disturb far less than the wall-clock one;
- the view's CPU use and the state events a second the page got (at most 30, whatever the sim's rate).

Printed: each phase, then the means and the ratios to the sim alone.

Run: . scripts/env.sh && ROS_DOMAIN_ID=43 python benchmarks/bench_view.py [--seconds S] [--rounds N]
"""
from __future__ import annotations

import argparse
import http.client
import json
import os
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import rclpy
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rosgraph_msgs.msg import Clock

from epuck_ros.bringup.processes import interrupt
from measure import cpu_seconds


def _executable(name: str) -> str:
    return shutil.which(name) or str(Path(sys.executable).parent / name)


class ClockSampler:
    """The newest /clock, read on demand; between reads the subscription holds one sample and nothing is spun."""

    def __init__(self) -> None:
        self.node = rclpy.create_node('bench_view_clock')
        self.latest: float | None = None
        self.node.create_subscription(Clock, '/clock', self._on_clock,
                                      QoSProfile(depth=1, reliability=qos_profile_sensor_data.reliability))

    def _on_clock(self, msg: Clock) -> None:
        self.latest = msg.clock.sec + msg.clock.nanosec * 1e-9

    def sample(self, timeout: float = 30.0) -> tuple[float, float]:
        """(wall time, simulated time) of a /clock newer than the last one read."""
        previous, self.latest = self.latest, None
        deadline = time.monotonic() + timeout
        while self.latest is None or self.latest == previous:
            if time.monotonic() > deadline:
                raise SystemExit('no /clock from the sim within 30 s')
            rclpy.spin_once(self.node, timeout_sec=0.1)
        return time.monotonic(), self.latest

    def measure(self, seconds: float, sim_pid: int, view_pid: int | None = None) -> Phase:
        """Real-time factor and CPU use over `seconds` of wall time."""
        sim_cpu0, view_cpu0 = cpu_seconds(sim_pid), cpu_seconds(view_pid) if view_pid else 0.0
        wall0, sim0 = self.sample()
        time.sleep(seconds)
        wall1, sim1 = self.sample()
        sim_cpu, view_cpu = cpu_seconds(sim_pid) - sim_cpu0, (cpu_seconds(view_pid) - view_cpu0) if view_pid else 0.0
        return Phase(rtf=(sim1 - sim0) / (wall1 - wall0), sim_cpu_per_sim_second=sim_cpu / (sim1 - sim0),
                     view_cores=view_cpu / (wall1 - wall0))


@dataclass
class Phase:
    rtf: float
    sim_cpu_per_sim_second: float
    view_cores: float
    page_events: float = 0.0

    def __str__(self) -> str:
        text = (f'{self.rtf:6.0f}x real time; sim CPU {1e3 * self.sim_cpu_per_sim_second:6.2f} ms per simulated s '
                f'(= {1 / self.sim_cpu_per_sim_second:4.0f}x on a core of its own)')
        if self.view_cores:
            text += f'; view {100 * self.view_cores:3.0f} % of a core'
        return text + (f'; page {self.page_events:.0f} events/s' if self.page_events else '')


class Page:
    """A client of the view's event stream, counting the state events it receives."""

    def __init__(self, host: str, port: int) -> None:
        self.states = 0
        self._connection = http.client.HTTPConnection(host, port, timeout=30)
        self._connection.request('GET', '/events?robot=epuck')  # as the page does, showing the robot in detail
        self._response = self._connection.getresponse()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        try:
            for line in self._response:
                if line.startswith(b'event: state'):
                    self.states += 1
        except (OSError, ValueError):
            pass  # closed at the end of the phase

    def close(self) -> None:
        self._connection.close()


def start_view(log: Path) -> tuple[subprocess.Popen, str, int]:
    """The view on a free port; returns it once it printed its URL and answers HTTP."""
    view = subprocess.Popen([_executable('view'), '--ros-args', '-p', 'port:=0'], stdout=open(log, 'w'),
                            stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONUNBUFFERED='1'))
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        for line in log.read_text().splitlines():
            if line.startswith('view: http://'):
                host, port = line.split('//')[1].rstrip('/').rsplit(':', 1)
                return view, host, int(port)
        if view.poll() is not None:
            break
        time.sleep(0.1)
    raise SystemExit(f'the view did not start:\n{log.read_text()}')


def get(host: str, port: int, path: str) -> str:
    connection = http.client.HTTPConnection(host, port, timeout=30)
    connection.request('GET', path)
    body = connection.getresponse().read().decode()
    connection.close()
    return body


def wait_for(condition: Callable[[], bool], what: str, timeout: float = 60.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise SystemExit(f'timed out waiting for {what}')
        time.sleep(0.05)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=5.0, help='wall seconds per phase (default 5)')
    parser.add_argument('--rounds', type=int, default=2, help='rounds of the three phases (default 2)')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    sim = subprocess.Popen([_executable('sim'), '--ros-args', '-p', 'real_time_factor:=0.0'],
                           stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    rclpy.init()
    sampler = ClockSampler()
    phases: dict[str, list[Phase]] = {'sim alone': [], 'sim + view, no page': [], 'sim + view + page': []}
    try:
        sampler.sample()
        for _ in range(args.rounds):
            phases['sim alone'].append(sampler.measure(args.seconds, sim.pid))
            print(f'sim alone:            {phases["sim alone"][-1]}', flush=True)
            view, host, port = start_view(Path('/tmp') / f'bench_view_{os.getpid()}.log')
            try:
                wait_for(lambda: 'robots' in json.loads(get(host, port, '/world')), 'the view to have the world')
                phases['sim + view, no page'].append(sampler.measure(args.seconds, sim.pid, view.pid))
                print(f'sim + view, no page:  {phases["sim + view, no page"][-1]}', flush=True)
                page = Page(host, port)
                wait_for(lambda: page.states > 0, 'the first frame on the page')
                states = page.states
                phase = sampler.measure(args.seconds, sim.pid, view.pid)
                phase.page_events = (page.states - states) / args.seconds
                phases['sim + view + page'].append(phase)
                page.close()
            finally:
                interrupt(view, 10)
            print(f'sim + view + page:    {phases["sim + view + page"][-1]}', flush=True)
    finally:
        sampler.node.destroy_node()
        rclpy.try_shutdown()
        interrupt(sim, 10)
    means = {name: Phase(*(sum(getattr(p, f) for p in runs) / len(runs) for f in
                           ('rtf', 'sim_cpu_per_sim_second', 'view_cores', 'page_events')))
             for name, runs in phases.items()}
    alone = means['sim alone']
    print('means:')
    for name, mean in means.items():
        print(f'  {name + ":":22}{mean}')
        if name != 'sim alone':
            print(f'  {"":22}ratio to the sim alone: real-time factor {mean.rtf / alone.rtf:.2f}, '
                  f'sim CPU per simulated second {mean.sim_cpu_per_sim_second / alone.sim_cpu_per_sim_second:.2f}')


if __name__ == '__main__':
    main()
