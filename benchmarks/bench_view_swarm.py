"""Does the live view keep up with a swarm, and what does it cost the simulator? One `sim` of N robots (default
1,000) in a 10 m x 10 m arena at `real_time_factor` 0, then the `view` beside it, then a page on the view.

Per phase (sim alone; sim + view, no page; sim + view + page):
- the simulator's real-time factor (/clock sampled at the start and end of the phase by a
  best-effort depth-1 subscription) and its CPU time per simulated second (Linux /proc);
- the view's CPU use (cores) and resident memory (MB);
- with a page (showing `--robot` in detail): the wall seconds from the page's connection to the first state event
  that holds every robot's pose, the state events a second it then got and their mean size;
- after the phase: the robots' own topics the graph shows (`/<robot>/...`: from 200 robots the simulator makes a
  robot's topics only once someone reads them).
`--browser`: before the page client, a headless Chromium (as test_view_browser) opens the page: the seconds from
opening the URL until the page has drawn every robot (`window.epuckView.drawn`), and how long one drawing takes
once the trails have grown for 5 s.
`--foxglove`: the Foxglove bridge instead of the view (`foxglove --port 0`): alone, then with a WebSocket client
subscribed to `--channels` (default `/swarm/observation` and `/tf`: what a swarm's plot and 3D panel read), the
channels it advertised, the messages a second the client got.

Run: . scripts/env.sh && ROS_DOMAIN_ID=42 python benchmarks/bench_view_swarm.py [--robots N] [--seconds S]
[--browser]
"""
from __future__ import annotations

import argparse
import http.client
import json
import os
import re
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import rclpy

from bench_view import ClockSampler, _executable, get, start_view, wait_for
from epuck_ros.bringup.processes import interrupt
from measure import cpu_seconds


def resident_mb(pid: int) -> float:
    """The process's resident memory (VmRSS) in MB."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1]) / 1024
    return float('nan')


def robot_topics(node: rclpy.node.Node, robots: set[str]) -> list[str]:
    """The graph's topics under a robot's name."""
    return sorted(name for name, _ in node.get_topic_names_and_types()
                  if (m := re.match(r'/([^/]+)/', name)) and m.group(1) in robots)


class Page:
    """A client of the view's event stream as the page is (showing `robot` in detail): when the first state event
    with every robot's pose came, how many state events and bytes followed."""

    def __init__(self, host: str, port: int, robot: str, robots: int) -> None:
        self.opened = time.monotonic()
        self.complete: float | None = None
        self.states, self.state_bytes = 0, 0
        self._robots = robots
        self._connection = http.client.HTTPConnection(host, port, timeout=60)
        self._connection.request('GET', f'/events?robot={robot}')
        self._response = self._connection.getresponse()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        kind = ''
        try:
            for line in self._response:
                if line.startswith(b'event: '):
                    kind = line[7:].strip().decode()
                elif line.startswith(b'data: ') and kind == 'state':
                    self.states += 1
                    self.state_bytes += len(line)
                    if self.complete is None and self._all_posed(line[6:]):
                        self.complete = time.monotonic()
        except (OSError, ValueError):
            pass   # closed at the end of the phase

    def _all_posed(self, data: bytes) -> bool:
        robots = json.loads(data)['robots']
        poses = robots.get('pose') if 'pose' in robots and isinstance(robots['pose'], list) else None
        if poses is not None:   # columns: a list of poses
            return len(poses) == self._robots and all(p is not None for p in poses)
        return len(robots) == self._robots and all(r.get('pose') is not None for r in robots.values())

    def close(self) -> None:
        self._connection.close()


def browser_seconds(url: str, robots: int) -> tuple[float, float]:
    """Seconds from opening the page in a headless Chromium until it has drawn every robot, and then the
    milliseconds one drawing of the canvas takes 5 s later (the mean of ten)."""
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.support.ui import WebDriverWait
    options = webdriver.ChromeOptions()
    options.binary_location = '/usr/bin/chromium'
    profile = tempfile.mkdtemp(prefix='bench_view_chromium_')
    for argument in ('--headless=new', '--no-sandbox', '--disable-gpu', '--window-size=1200,760',
                     f'--user-data-dir={profile}'):
        options.add_argument(argument)
    driver = webdriver.Chrome(options=options, service=Service('/usr/bin/chromedriver'))
    try:
        started = time.monotonic()
        driver.get(url)
        drawn = ('const d = window.epuckView.drawn; return d && d.robots ? '
                 'Object.values(d.robots).filter(r => r.pose).length : 0')
        WebDriverWait(driver, 300, poll_frequency=0.05).until(lambda d: d.execute_script(drawn) == robots)
        seconds = time.monotonic() - started
        time.sleep(5.0)   # the trails grow
        return seconds, driver.execute_script(
            'const t = performance.now(); for (let i = 0; i < 10; i++) draw(); return (performance.now() - t) / 10')
    finally:
        driver.quit()


def measure(sampler: ClockSampler, seconds: float, sim: int, view: int | None) -> dict:
    cpu0 = cpu_seconds(sim), cpu_seconds(view) if view else 0.0
    wall0, sim0 = sampler.sample(120.0)
    time.sleep(seconds)
    wall1, sim1 = sampler.sample(120.0)
    result = {'rtf': (sim1 - sim0) / (wall1 - wall0), 'sim_cpu_ms_per_sim_s': 1e3 * (cpu_seconds(sim) - cpu0[0])
              / (sim1 - sim0)}
    if view:
        result.update(view_cores=(cpu_seconds(view) - cpu0[1]) / (wall1 - wall0), view_mb=resident_mb(view))
    return result


def _show(name: str, figures: dict) -> None:
    print(f'{name}: ' + ', '.join(f'{key} {value:.3g}' if isinstance(value, float) else f'{key} {value}'
                                  for key, value in figures.items()), flush=True)


class FoxgloveClient:
    """A Foxglove WebSocket client (the protocol's JSON control messages; binary messageData only counted)."""

    def __init__(self, port: int) -> None:
        import websocket
        self.ws = websocket.create_connection(f'ws://127.0.0.1:{port}', subprotocols=['foxglove.sdk.v1'], timeout=60)
        self.channels: dict[str, int] = {}
        self.messages = 0
        self._ids = iter(range(1, 1 << 30))
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        try:
            while True:
                opcode, data = self.ws.recv_data()
                if opcode == 1:   # text: control
                    message = json.loads(data)
                    if message['op'] == 'advertise':
                        self.channels.update({c['topic']: c['id'] for c in message['channels']})
                elif data[0] == 1:   # messageData
                    self.messages += 1
        except Exception:   # noqa: BLE001 - closed at the end
            pass

    def subscribe(self, *topics: str) -> None:
        self.ws.send(json.dumps({'op': 'subscribe', 'subscriptions': [
            {'id': next(self._ids), 'channelId': self.channels[topic]} for topic in topics]}))


def _foxglove_phases(args: argparse.Namespace, sampler: ClockSampler, sim: subprocess.Popen, names: set[str]) -> None:
    _show('sim alone', measure(sampler, args.seconds, sim.pid, None))
    log = Path(tempfile.gettempdir()) / f'bench_view_swarm_foxglove_{os.getpid()}.log'
    bridge = subprocess.Popen([_executable('foxglove'), '--port', '0'], stdout=open(log, 'w'),
                              stderr=subprocess.STDOUT, env=dict(os.environ, PYTHONUNBUFFERED='1'))
    try:
        wait_for(lambda: 'ws://' in log.read_text(), 'the bridge to serve', 60)
        port = int(re.search(r'ws://127\.0\.0\.1:(\d+)', log.read_text()).group(1))
        _show('sim + foxglove, no client', {**measure(sampler, args.seconds, sim.pid, bridge.pid),
                                            'robot_topics': len(robot_topics(sampler.node, names))})
        client = FoxgloveClient(port)
        wait_for(lambda: set(args.channels) <= set(client.channels), f'the channels {args.channels}', 60)
        client.subscribe(*args.channels)
        wait_for(lambda: client.messages > 0, 'the first forwarded message', 60)
        count = client.messages
        figures = measure(sampler, args.seconds, sim.pid, bridge.pid)
        _show(f'sim + foxglove + client on {" ".join(args.channels)}', {
            **figures, 'messages_per_s': (client.messages - count) / args.seconds,
            'channels': len(client.channels), 'robot_topics': len(robot_topics(sampler.node, names))})
        client.ws.close()
    finally:
        interrupt(bridge, 10)


def _phases(args: argparse.Namespace, sampler: ClockSampler, sim: subprocess.Popen, names: set[str]) -> None:
    _show('sim alone', measure(sampler, args.seconds, sim.pid, None))
    view, host, port = start_view(Path(tempfile.gettempdir()) / f'bench_view_swarm_{os.getpid()}.log')
    try:
        wait_for(lambda: len(json.loads(get(host, port, '/world')).get('robots', [])) == args.robots,
                 'the view to have the world', 120)
        _show('sim + view, no page', {**measure(sampler, args.seconds, sim.pid, view.pid),
                                      'robot_topics': len(robot_topics(sampler.node, names))})
        if args.browser:
            seconds, draw_ms = browser_seconds(f'http://{host}:{port}/', args.robots)
            _show('browser', {'seconds_to_draw_every_robot': seconds, 'ms_per_drawing': draw_ms})
        page = Page(host, port, args.robot, args.robots)
        wait_for(lambda: page.complete is not None, 'a state with every robot', 300)
        states, size = page.states, page.state_bytes
        figures = measure(sampler, args.seconds, sim.pid, view.pid)
        figures.update(first_full_state_s=page.complete - page.opened,
                       states_per_s=(page.states - states) / args.seconds,
                       state_kb=(page.state_bytes - size) / max(1, page.states - states) / 1e3)
        page.close()
        topics = robot_topics(sampler.node, names)
        _show('sim + view + page', {**figures, 'robot_topics': len(topics)})
        print('  robots with topics:', sorted({t.split('/')[1] for t in topics})[:5], flush=True)
    finally:
        interrupt(view, 10)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--robots', type=int, default=1000)
    parser.add_argument('--seconds', type=float, default=5.0, help='wall seconds per phase (default 5)')
    parser.add_argument('--browser', action='store_true', help='also time a headless Chromium drawing the robots')
    parser.add_argument('--robot', default='epuck0',
                        help="the robot the page shows in detail (its camera is rendered); '' for none")
    parser.add_argument('--foxglove', action='store_true', help='the Foxglove bridge instead of the view')
    parser.add_argument('--channels', nargs='+', default=['/swarm/observation', '/tf'],
                        help='with --foxglove: the topics the client subscribes to')
    args = parser.parse_args()
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    world = Path(tempfile.mkdtemp(prefix='bench_view_swarm_')) / 'arena10.yaml'
    world.write_text('arena: {size: [10.0, 10.0]}\n')
    started = time.monotonic()
    sim = subprocess.Popen([_executable('sim'), '--ros-args', '-p', f'robots:={args.robots}', '-p',
                            f'world:={world}', '-p', 'real_time_factor:=0.0'],
                           stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    rclpy.init()
    sampler = ClockSampler()
    try:
        sampler.sample(300.0)
        print(f'{args.robots} robots; sim stepping after {time.monotonic() - started:.1f} s; load average '
              f'{os.getloadavg()[0]:.2f} on {os.cpu_count()} cores', flush=True)
        (_foxglove_phases if args.foxglove else _phases)(args, sampler, sim, {f'epuck{i}' for i in range(args.robots)})
    finally:
        sampler.node.destroy_node()
        rclpy.try_shutdown()
        interrupt(sim, 10)


if __name__ == '__main__':
    main()
