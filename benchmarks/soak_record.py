"""Recorder soak: the `record` executable's memory over a long recording at full speed.

Starts the simulator at ``real_time_factor`` 0 (or, with ``--synthetic``, a child process publishing the
sim's traffic mix as fast as it can), records it with `record` in its own process, and prints the
recorder's resident memory (VmRSS from /proc/<pid>/status) every ``--interval`` seconds with the
bag's size so far. At the end: messages recorded, RSS growth per message recorded (a recorder that
leaks a few hundred bytes per message shows here at once), and what `record` and `bag info` say about
lost messages (at real_time_factor 0 without lockstep the simulator may outrun the recorder).

Run: python benchmarks/soak_record.py [--minutes 10] [--interval 30] [--synthetic] [--keep]
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from epuck_ros.bag.info import format_info
from epuck_ros.bag.reader import Bag
from epuck_ros.testing.simulator import claim_free_domain

BIN = Path(sys.executable).parent


def rss_kib(pid: int) -> int:
    """Resident set size of a process in KiB (psutil is not installed: /proc has it)."""
    for line in Path(f'/proc/{pid}/status').read_text().splitlines():
        if line.startswith('VmRSS:'):
            return int(line.split()[1])
    raise RuntimeError(f'no VmRSS for pid {pid}')


def bag_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.glob('*.mcap'))


def synthetic_publisher(domain: int) -> subprocess.Popen:
    """A child process publishing the sim's 12 messages per step as fast as it can (bench_bag's traffic)."""
    code = (
        'import rclpy, sys\n'
        'sys.path.insert(0, sys.argv[1])\n'
        'from bench_bag import sim_traffic, TOPICS\n'
        'from rclpy.qos import QoSProfile\n'
        'from rosgraph_msgs.msg import Clock\n'
        'from nav_msgs.msg import Odometry\n'
        'from sensor_msgs.msg import JointState, Range\n'
        'rclpy.init()\n'
        'node = rclpy.create_node("soak_publisher")\n'
        'classes = {"/clock": Clock, "/odom": Odometry, "/ground_truth": Odometry, "/proximity": Range,'
        ' "/joint_states": JointState}\n'
        'pubs = {t: node.create_publisher(c, t, QoSProfile(depth=100)) for t, c in classes.items()}\n'
        'try:\n'
        '    for topic, data, _ in sim_traffic(10**9):\n'
        '        pubs[topic].publish(bytes(data))\n'
        'except KeyboardInterrupt:\n'
        '    pass\n')
    return subprocess.Popen([sys.executable, '-c', code, str(Path(__file__).parent)],
                            env=dict(os.environ, ROS_DOMAIN_ID=str(domain)), start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)


def stop(process: subprocess.Popen, timeout: float = 30.0) -> int:
    """SIGINT, then SIGKILL if it has not ended after `timeout`."""
    if process.poll() is None:
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return process.returncode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--minutes', type=float, default=10.0, help='recording length (default 10)')
    parser.add_argument('--interval', type=float, default=30.0, help='seconds between RSS samples (default 30)')
    parser.add_argument('--synthetic', action='store_true',
                        help='publish synthetic sim traffic from a child process instead of running `sim`')
    parser.add_argument('--compression', default='zstd', choices=('none', 'zstd', 'lz4'),
                        help='bag compression (default zstd: 10 min at full speed is GBs uncompressed)')
    parser.add_argument('--keep', action='store_true', help='keep the bag (folder printed)')
    args = parser.parse_args()
    domain, _claim = claim_free_domain()   # held while this process lives (domain_coordinator)
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               PYTHONUNBUFFERED='1')
    workdir = Path(tempfile.mkdtemp(prefix='epuck_soak_record_'))
    bag = workdir / 'soak'
    source_name = 'synthetic publisher' if args.synthetic else 'sim at real_time_factor 0'
    print(f'recording the {source_name} for {args.minutes:g} min on ROS_DOMAIN_ID={domain} to {bag}')
    log = open(workdir / 'processes.log', 'w')
    if args.synthetic:
        source = synthetic_publisher(domain)
    else:
        source = subprocess.Popen([str(BIN / 'sim'), '--ros-args', '-p', 'real_time_factor:=0.0'], env=env,
                                  stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    recorder = subprocess.Popen([str(BIN / 'record'), '-o', str(bag), '--compression', args.compression,
                                 '--ros-args', '-p', 'use_sim_time:=true'], env=env, stdout=log,
                                stderr=subprocess.STDOUT, start_new_session=True)
    samples: list[tuple[float, int]] = []
    try:
        begin = time.monotonic()
        end = begin + args.minutes * 60.0
        print(f'{"minute":>7} {"RSS MiB":>8} {"bag MiB":>8}')
        while True:
            now = time.monotonic()
            if recorder.poll() is not None or source.poll() is not None:
                raise SystemExit(f'a process ended early; see {workdir / "processes.log"}')
            samples.append((now - begin, rss_kib(recorder.pid)))
            print(f'{(now - begin) / 60:7.2f} {samples[-1][1] / 1024:8.1f} {bag_bytes(bag) / 2**20:8.1f}',
                  flush=True)
            if now >= end:
                break
            time.sleep(min(args.interval, max(0.0, end - time.monotonic())))
        stop(source)
        status = stop(recorder, timeout=120.0)
        log.close()
        with Bag(bag) as recorded:
            count = recorded.message_count
            info = format_info(recorded)
        settle = min(60.0, samples[-1][0] / 3)  # start-up: DDS, imports, the first chunk buffers
        first_minute = next(kib for t, kib in samples if t >= settle)
        growth = (samples[-1][1] - first_minute) * 1024
        print(f'recorder exit code {status}; {count:,} messages recorded '
              f'({count / (args.minutes * 60):,.0f} msg/s)')
        print(f'RSS: {samples[0][1] / 1024:.1f} MiB at start, {first_minute / 1024:.1f} MiB after {settle:.0f} s, '
              f'{samples[-1][1] / 1024:.1f} MiB at the end, max {max(k for _, k in samples) / 1024:.1f} MiB; '
              f'growth after that {growth / max(count, 1):.2f} bytes per message '
              f'(the leaking recorder: ~280)')
        report = [line.split(']: ', 1)[-1] for line in (workdir / 'processes.log').read_text().splitlines()
                  if 'lost' in line]
        print('\n'.join(f'record says: {line}' for line in report))
        print('\n'.join(line for line in info.splitlines()
                        if 'Messages' in line or 'missing' in line or 'Stamp gaps' in line))
    finally:
        for process in (source, recorder):
            stop(process, timeout=5.0)
        if args.keep:
            print(f'bag kept in {workdir}')
        else:
            shutil.rmtree(workdir, ignore_errors=True)


if __name__ == '__main__':
    main()
