"""What the wheel commands a controller keeps cost in memory: `ack_window.command_qos` keeps a writer's last
`history_steps` commands (transient local), so that a recorder matched late still gets them.

WRITERS publishers of `wheel_cmd` with `command_qos(1)` (a Webots script's: 3,000 commands kept) each publish COMMANDS
commands as a controller answers steps (two wheel speeds, named by the step), with no reader: every one is kept.
Printed: the process's resident memory before and after, and per command kept.

Run: . scripts/env.sh && ROS_DOMAIN_ID=70 python benchmarks/bench_command_history.py [--writers N] [--commands N]
"""
from __future__ import annotations

import argparse
import gc

import rclpy
from std_msgs.msg import Float64MultiArray

from epuck_ros.ros.ack_window import command_qos
from epuck_ros.ros.serialized import array_bytes


def resident_bytes() -> int:
    """This process's resident memory (Linux /proc)."""
    with open('/proc/self/status', encoding='ascii') as status:
        return next(int(line.split()[1]) * 1024 for line in status if line.startswith('VmRSS:'))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--writers', type=int, default=20)
    parser.add_argument('--commands', type=int, default=3000)
    args = parser.parse_args()
    rclpy.init()
    try:
        node = rclpy.create_node('bench_command_history')
        writers = [node.create_publisher(Float64MultiArray, f'robot{index}/wheel_cmd', command_qos(1))
                   for index in range(args.writers)]
        gc.collect()
        before = resident_bytes()
        for step in range(1, args.commands + 1):
            stamp = divmod(step * 32_000_000, 1_000_000_000)
            for writer in writers:
                writer.publish(array_bytes([1.0, -1.0], stamp))
        gc.collect()
        after = resident_bytes()
        kept = args.writers * args.commands
        print(f'{args.writers} writers x {args.commands} commands: resident {before / 1e6:.1f} MB -> '
              f'{after / 1e6:.1f} MB, {(after - before) / 1e6:.1f} MB more, {(after - before) / kept / 1e3:.2f} KB a '
              f'command kept')
        node.destroy_node()
    finally:
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
