"""`webots_controller SCRIPT --headless`: one Webots-style script against the pure core, in this process, no ROS.

The run is that of `bringup --controller SCRIPT --lockstep --real-time-factor 0` with the same world, seed and
duration (`trial.run`), at the core's speed; the script's output goes to the terminal as usual, and the end is
`bringup`'s summary, computed by the same code. Exit code: 0, 1 when the script failed (its traceback above), 2 for
a bad command line or a recording the disk cannot hold, 130 (Ctrl-C) or 143 (SIGTERM) for a run cut short.
"""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from epuck_ros.bag.shapes import Motion, classify_runs
from epuck_ros.bringup import summary
from epuck_ros.conversions import nanoseconds_from_stamp, stamp_from_seconds
from epuck_ros.exit_codes import EXIT_BAD_INPUT, EXIT_FAILED
from epuck_ros.experiments.interruption import exit_code, terminate_as_interrupt
from epuck_ros.experiments.record_budget import LARGE, RecordRefused, check_room, estimate
from epuck_ros.experiments.spec import MAX_DURATION, MAX_ROBOTS
from epuck_ros.experiments.trial import DEFAULT_WORLD, Script, Trial, run
from epuck_ros.model import TIME_STEP
from epuck_ros.simulation import MAX_SEED, Simulation
from epuck_ros.webots.headless import ScriptError
from epuck_ros.webots.script_file import FileMissing, FileProblem, read_script
from epuck_ros.world import World, WorldError

if TYPE_CHECKING:
    from epuck_ros.experiments.recording import TrialRecorder

PROGRAM = 'webots_controller'
MAX_SHAPE_SAMPLES = 2_000_000
"""Robot-steps of ground truth kept for the shapes driven, at most (64 MB): one robot for an hour is 112,500."""


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
    try:
        read_script(args.script)
    except FileMissing:
        parser.error(f'no such controller script: {args.script}')
    except FileProblem as problem:
        parser.error(f'controller script {args.script}: {problem}')
    if not 0 < args.duration <= MAX_DURATION:
        parser.error(f'--duration must be above 0 and at most {MAX_DURATION:g} simulated seconds')
    if not 0 <= args.robots <= MAX_ROBOTS:
        parser.error(f'--robots must be from 1 to {MAX_ROBOTS}')
    if not 0 <= args.seed <= MAX_SEED:
        parser.error(f'--seed must be from 0 to {MAX_SEED} (as bringup --seed)')
    if args.world != DEFAULT_WORLD and not Path(args.world).is_file():
        parser.error(f'--world: no such file: {args.world}')
    if args.record is not None and os.path.lexists(args.record):
        parser.error(f'--record {args.record}: already exists (pick a new folder)')
    world = args.world if args.world == DEFAULT_WORLD else str(Path(args.world).resolve())
    trial = Trial(Script(str(args.script.resolve())), world, args.robots if args.robots > 1 else 0, args.seed,
                  args.duration, not args.no_noise)
    try:
        trial.load_world()
    except WorldError as error:
        parser.error(f'--world {args.world}: {error}' if args.world != DEFAULT_WORLD else str(error))
    return trial


def start_recording(parser: argparse.ArgumentParser, args: argparse.Namespace, world: World) -> TrialRecorder:
    """The recorder of --record, once the disk is known to hold it (said first when the bag will be large)."""
    from epuck_ros.experiments.recording import TrialRecorder
    try:
        size = estimate([(len(world.robots), args.duration)])
        line = check_room(args.record.parent, size, f'--record {args.record}')
        if size >= LARGE:
            print(f'[{PROGRAM}] {line}', flush=True)
        return TrialRecorder(args.record, world, controller_robots=1)   # a script: one process per robot over ROS
    except RecordRefused as error:
        parser.error(str(error))
    except OSError as error:
        parser.error(f'--record {args.record}: cannot write there: {error.strerror or error}')


class Tracks:
    """Every robot's ground truth at each step, for the shape it drove (`summary.trajectory_of_track`): kept in arrays
    of 32 bytes per robot-step, and only when the run's robot-steps are at most MAX_SHAPE_SAMPLES (a large or long
    run is summed up without its shapes; distance and contacts are counted as it runs, whatever its size)."""

    def __init__(self, robots: int, duration: float) -> None:
        steps = math.ceil(duration / TIME_STEP) + 2   # the first step, and the one at or after the duration
        self.kept = robots * steps <= MAX_SHAPE_SAMPLES
        self.stamps = np.empty(steps if self.kept else 0, np.int64)
        self.poses = np.empty((len(self.stamps), robots, 3))
        self.count = 0

    def add(self, stamp: int, poses: np.ndarray) -> None:
        if self.kept and self.count == len(self.stamps):   # more steps than the duration makes: no shapes, not
            self.kept = False                               # shapes of a part of the run
        if self.kept:
            self.stamps[self.count] = stamp
            self.poses[self.count] = poses
            self.count += 1

    def motions(self, labels: list[str], world: World) -> dict[str, Motion]:
        """Each robot's shape under its label in `summary.lines`, in `world` with the others; none when the samples
        were not kept."""
        if not self.kept:
            return {}
        poses, stamps = self.poses[:self.count], self.stamps[:self.count]
        return classify_runs({label: summary.trajectory_of_track(stamps, poses[:, i, 0], poses[:, i, 1], poses[:, i, 2])
                              for i, label in enumerate(labels)}, world)


def main(argv: list[str]) -> None:
    parser = build_parser()
    args = parser.parse_args(argv)
    trial = check(parser, args)
    world = trial.load_world()
    tracks = Tracks(len(world.robots), trial.duration)
    recorder = start_recording(parser, args, world) if args.record is not None else None

    def each_step(sim: Simulation) -> None:
        tracks.add(nanoseconds_from_stamp(*stamp_from_seconds(sim.time)), sim.true_pose)

    began = time.perf_counter()
    try:
        with terminate_as_interrupt():
            sim, tally = run(trial, each_step=each_step, recorder=recorder)
    except ScriptError as error:
        if error.code == EXIT_BAD_INPUT:   # refused, and said in one line by the script's runner (webots.runner)
            raise SystemExit(EXIT_BAD_INPUT) from None
        print(f'{PROGRAM}: {error}', file=sys.stderr)
        raise SystemExit(EXIT_FAILED) from None
    except KeyboardInterrupt as interruption:   # Ctrl-C or SIGTERM: the run is cut short (the bag is closed)
        print(f'[{PROGRAM}] interrupted' + (f'; recorded to {args.record}' if recorder is not None else ''),
              flush=True)
        raise SystemExit(exit_code(interruption)) from None
    finally:
        if recorder is not None:
            recorder.close()
    wall = time.perf_counter() - began
    several = len(sim.names) > 1
    lines = [f'simulated {sim.time:.2f} s in {wall:.2f} s wall ({sim.time / wall:.0f}x real time), headless']
    lines += summary.lines(tally.figures, tracks.motions([name if several else '' for name in sim.names], sim.world))
    if not tracks.kept:
        lines.append(f'shapes not classified: {len(sim.names)} robots x {sim.steps} steps, more than the '
                     f'{MAX_SHAPE_SAMPLES} samples kept for them (`bag summary` of a --record bag classifies them)')
    if args.record is not None:
        lines.append(f'recorded to {args.record} (bag summary {args.record} says more)')
    print('\n'.join(f'[{PROGRAM}] {line}' for line in lines), flush=True)
