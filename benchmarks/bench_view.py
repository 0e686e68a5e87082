"""Does the live view slow the simulator down? The `sim` node's real-time factor at `real_time_factor` 0, alone and
with the `view` node running and a page connected to it.

One `sim` process (default world, noise on) runs throughout; the phases alternate: sim alone, sim + view with no
page open (as `bringup --view` before a browser connects), sim + view + page, and so on. The page is a client reading the view's event stream (`/events`) as a browser does. The real-time
factor is the simulated time /clock advanced over the wall time of the phase, read by a best-effort, depth-1
subscription sampled only at the start and the end of each phase (so measuring costs the sim nothing).

Printed: the real-time factor of each phase, the means, their ratio (with / without), the state events a second
the page received (the view thins them to at most 30 a second whatever the simulator's rate) and the CPU time the
view process used (on a machine with few cores, that is what the simulator may lose).

Run: . scripts/env.sh && ROS_DOMAIN_ID=43 python benchmarks/bench_view.py [--seconds S] [--rounds N]
"""
from __future__ import annotations

import argparse
import http.client
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import rclpy
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rosgraph_msgs.msg import Clock


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

    def real_time_factor(self, seconds: float) -> float:
        wall0, sim0 = self.sample()
        time.sleep(seconds)
        wall1, sim1 = self.sample()
        return (sim1 - sim0) / (wall1 - wall0)


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


def cpu_seconds(pid: int) -> float:
    """User + system CPU time a process has used (Linux /proc)."""
    fields = Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def stop(process: subprocess.Popen) -> None:
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


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
    alone, unwatched, viewed, event_rates, view_cpu = [], [], [], [], []
    try:
        sampler.sample()
        for _ in range(args.rounds):
            alone.append(sampler.real_time_factor(args.seconds))
            print(f'sim alone:            {alone[-1]:7.0f}x real time', flush=True)
            view, host, port = start_view(Path('/tmp') / f'bench_view_{os.getpid()}.log')
            try:
                wait_for(lambda: 'robots' in json.loads(get(host, port, '/world')), 'the view to have the world')
                unwatched.append(sampler.real_time_factor(args.seconds))
                print(f'sim + view, no page:  {unwatched[-1]:7.0f}x real time', flush=True)
                page = Page(host, port)
                wait_for(lambda: page.states > 0, 'the first frame on the page')
                states, cpu = page.states, cpu_seconds(view.pid)
                viewed.append(sampler.real_time_factor(args.seconds))
                event_rates.append((page.states - states) / args.seconds)
                view_cpu.append((cpu_seconds(view.pid) - cpu) / args.seconds)
                page.close()
            finally:
                stop(view)
            print(f'sim + view + page:    {viewed[-1]:7.0f}x real time '
                  f'(the page got {event_rates[-1]:.0f} state events/s; '
                  f'the view used {100 * view_cpu[-1]:.0f} % of a core)', flush=True)
    finally:
        sampler.node.destroy_node()
        rclpy.try_shutdown()
        stop(sim)
    mean = {name: sum(values) / len(values) for name, values in
            (('alone', alone), ('unwatched', unwatched), ('viewed', viewed))}
    print(f'mean: sim alone {mean["alone"]:.0f}x; with the view and no page {mean["unwatched"]:.0f}x '
          f'(ratio {mean["unwatched"] / mean["alone"]:.2f}); with the view and a page {mean["viewed"]:.0f}x '
          f'(ratio {mean["viewed"] / mean["alone"]:.2f}); page events {max(event_rates):.0f}/s at most; '
          f'view CPU {100 * sum(view_cpu) / len(view_cpu):.0f} % of a core')

if __name__ == '__main__':
    main()
