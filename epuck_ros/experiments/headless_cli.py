"""`webots_controller SCRIPT --headless`: one Webots-style script against the pure core, in this process, no ROS.

The run is that of `bringup --controller SCRIPT --lockstep --real-time-factor 0` with the same world, seed and
duration (`trial.run`), at the core's speed; the script's output goes to the terminal as usual, and the end is
`bringup`'s summary, computed by the same code. Exit code: 0 (also after Ctrl-C), 1 when the script failed (its
traceback above), 2 for a bad command line.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from epuck_ros.bringup import summary
from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_seconds
from epuck_ros.experiments.spec import MAX_DURATION, MAX_ROBOTS
from epuck_ros.experiments.trial import DEFAULT_WORLD, Script, Trial, run
from epuck_ros.webots.headless import ScriptError
from epuck_ros.world import WorldError

PROGRAM = 'webots_controller'
EXIT_FAILED, EXIT_BAD_INPUT = 1, 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog=f'{PROGRAM} SCRIPT.py --headless',
        description='Run a Webots-style controller script against the e-puck core in this process, with no ROS, at '
                    'full speed: the same run as `bringup --controller SCRIPT.py --lockstep --real-time-factor 0` '
                    'with the same options, to the bit, and the same summary. Several robots each run the script '
                    '(as one webots_controller --robot NAME per robot would).',
        epilog=f'example: {PROGRAM} my_controller.py --headless --duration 60 --seed 3 --record run1')
    parser.add_argument('script', type=Path, help='the controller script (from controller import Robot ...)')
    parser.add_argument('--world', default=DEFAULT_WORLD, help='world YAML file (default: the built-in arena)')
    parser.add_argument('--robots', type=int, default=0, metavar='N',
                        help=f'N robots placed as `bringup --robots N` places them (1 to {MAX_ROBOTS}; default: '
                             'the world\'s own)')
    parser.add_argument('--seed', type=int, default=0, help='seed of every random draw (default 0)')
    parser.add_argument('--duration', type=float, default=60.0,
                        help=f'simulated seconds, ended on the first 32 ms step at or after it (default 60, at most '
                             f'{MAX_DURATION:g})')
    parser.add_argument('--no-noise', action='store_true', help='turn the sensor noise off')
    parser.add_argument('--record', metavar='BAG', type=Path,
                        help='write the run to a rosbag2 MCAP bag in folder BAG (as `bringup --record` would)')
    return parser


def check(parser: argparse.ArgumentParser, args: argparse.Namespace) -> Trial:
    if not args.script.is_file():
        parser.error(f'no such controller script: {args.script}')
    if not 0 < args.duration <= MAX_DURATION:
        parser.error(f'--duration must be above 0 and at most {MAX_DURATION:g} simulated seconds')
    if not 0 <= args.robots <= MAX_ROBOTS:
        parser.error(f'--robots must be from 1 to {MAX_ROBOTS}')
    if not 0 <= args.seed < 2**63:
        parser.error('--seed must be from 0 to 2**63 - 1')
    if args.world != DEFAULT_WORLD and not Path(args.world).is_file():
        parser.error(f'--world: no such file: {args.world}')
    if args.record is not None and args.record.exists():
        parser.error(f'--record {args.record}: already exists (pick a new folder)')
    world = args.world if args.world == DEFAULT_WORLD else str(Path(args.world).resolve())
    trial = Trial(Script(str(args.script.resolve())), world, args.robots if args.robots > 1 else 0, args.seed,
                  args.duration, not args.no_noise)
    try:
        trial.load_world()
    except WorldError as error:
        parser.error(f'--world {args.world}: {error}' if args.world != DEFAULT_WORLD else str(error))
    return trial


def main(argv: list[str]) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    trial = check(parser, args)
    samples: dict[str, list[tuple[int, float, float, float]]] = {}
    recorder = None
    if args.record is not None:
        from epuck_ros.experiments.recording import TrialRecorder
        recorder = TrialRecorder(args.record, trial.load_world())

    def each_step(sim: object) -> None:
        stamp = nanoseconds_from_stamp(*stamp_from_seconds(sim.time))
        for name, (x, y, yaw) in zip(sim.names, sim.true_pose.tolist()):
            samples.setdefault(name, []).append((stamp, x, y, yaw))

    began = time.perf_counter()
    try:
        sim, tally = run(trial, each_step=each_step, recorder=recorder)
    except ScriptError as error:
        print(f'{PROGRAM}: {error}', file=sys.stderr)
        raise SystemExit(EXIT_FAILED) from None
    except KeyboardInterrupt:   # Ctrl-C ends the run, as it ends one through bringup (the bag is closed)
        print(f'[{PROGRAM}] interrupted' + (f'; recorded to {args.record}' if recorder is not None else ''),
              flush=True)
        return
    finally:
        if recorder is not None:
            recorder.close()
    wall = time.perf_counter() - began
    several = len(sim.names) > 1
    motions = summary.motions_of({name if several else '': track for name, track in samples.items()}, sim.world)
    lines = [f'simulated {sim.time:.2f} s in {wall:.2f} s wall ({sim.time / wall:.0f}x real time), headless']
    lines += summary.lines(tally.figures, motions)
    if args.record is not None:
        lines.append(f'recorded to {args.record} (bag summary {args.record} says more)')
    print('\n'.join(f'[{PROGRAM}] {line}' for line in lines), flush=True)
