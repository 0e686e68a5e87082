"""bag: inspect and replay recorded runs (info, summary, plot, csv without ROS; play over ROS).

Each works on a bag folder or a single ``.mcap`` file. A bag that cannot be used gives one
line on stderr naming the file and the problem, and exit code 2.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
from collections.abc import Callable
from pathlib import Path

from epuck_ros.bag.cdr import CdrError
from epuck_ros.bag.export import export_csv
from epuck_ros.bag.info import format_info
from epuck_ros.bag.reader import Bag, BagError
from epuck_ros.bag.lockstep_status import recorded_integrity
from epuck_ros.bag.run_summary import BagSummary, summarise_runs
from epuck_ros.bag.runs import RunData, load_runs
from epuck_ros.bag.summary_text import format_bag_summary
from epuck_ros.exit_codes import refuse

PLOT_FORMATS = ('png', 'svg', 'pdf')
"""What `bag plot` writes, chosen by the output's extension."""


RATES = (0.001, 1000.0)
"""`bag play --rate` bounds: beyond them a bag's times no longer fit the playback clock's arithmetic (1e308
overflowed) and nothing useful is left (a thousandfold rate plays a minute in a blink)."""
CLOCK_HZ = (0.1, 10_000.0)
"""`bag play --clock` bounds: /clock publications per wall second."""
WAIT = (0.0, 3600.0)
"""`bag play --wait` bounds: wall seconds to look for the subscribers already running."""
DEFAULT_WAIT = 3.5
"""`bag play --wait` default: a node under Fast DDS's default profile announces itself every 3 s
(`ros.matching.FOREIGN_DISCOVERY_WINDOW`: equal, as test_bag_play checks; that module imports rclpy, this one
does not)."""


def _within(low: float, high: float) -> Callable[[str], float]:
    """An argparse type: a number from `low` to `high`, or one line naming the range."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f'must be from {low:g} to {high:g}, got {text}')
        return value
    return parse


def _info(args: argparse.Namespace) -> None:
    with Bag(args.path) as bag:
        print(format_info(bag))


def _runs(bag: Bag) -> tuple[list[RunData], BagSummary]:
    runs = load_runs(bag)
    return runs, summarise_runs(runs)


def _only(runs: list[RunData], summary: BagSummary, namespace: str | None,
          path: Path) -> tuple[list[RunData], BagSummary]:
    """One robot's part of a bag (robot-robot contacts were counted with every robot)."""
    if namespace is None:
        return runs, summary
    namespace = '/' + namespace.strip('/')
    names = [run.namespace for run in runs]
    if namespace not in names:
        raise BagError(f'{path}: no odometry under namespace {namespace} (robots: {", ".join(names)})')
    i = names.index(namespace)
    contacts = [c for c in summary.contacts if c.robot == runs[i].name]
    return [runs[i]], BagSummary(summary.bag, [summary.robots[i]], summary.robot_robot_contacts, contacts)


def _summary(args: argparse.Namespace) -> None:
    with Bag(args.path) as bag:
        runs, summary = _only(*_runs(bag), args.namespace, args.path)
        integrity = recorded_integrity(bag)
    if args.json:
        report = summary.to_dict()
        report['reproducible'] = None if integrity is None else integrity.reproducible
        report['reproducible_reason'] = None if integrity is None else integrity.reason
        print(json.dumps(report, indent=2))
        return
    verdict = 'unknown: the bag holds no lockstep_status' if integrity is None else integrity.verdict
    print(format_bag_summary(summary) + f'\n{"Reproducible:":<19}{verdict}')


def _plot(args: argparse.Namespace) -> None:
    suffix = args.output.suffix.lower().lstrip('.')
    if suffix not in PLOT_FORMATS:
        raise BagError(f'{args.output}: cannot write {"." + suffix if suffix else "a file without extension"}; '
                       f'use one of {", ".join("." + f for f in PLOT_FORMATS)}')
    from epuck_ros.bag.plot import plot_runs  # matplotlib is slow to import: only when plotting
    with Bag(args.path) as bag:
        runs, summary = _only(*_runs(bag), args.namespace, args.path)
    plot_runs(runs, summary, args.output)
    print(f'wrote {args.output}')


def _csv(args: argparse.Namespace) -> None:
    topic = '/' + args.topic.lstrip('/')  # `epuck3/odom` means /epuck3/odom, as `ros2 topic echo` takes it
    with Bag(args.path) as bag:
        if args.output is None:
            export_csv(bag, topic, sys.stdout, args.join_arrays)
            return
        with open(args.output, 'w', newline='', encoding='utf-8') as output:
            rows = export_csv(bag, topic, output, args.join_arrays)
    print(f'wrote {rows} rows to {args.output}', file=sys.stderr)


def _play(args: argparse.Namespace) -> None:
    from epuck_ros.nodes.play_node import play  # rclpy only for the one command that needs it
    play(args)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='bag', description=__doc__.split('\n\n')[0], formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog='example:\n  bag summary bags/circle\n\n`bag COMMAND --help` explains each command.')
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')
    _command(commands, 'info', _info, 'what ros2 bag info prints, plus topic rates; instant from the MCAP summary',
             ['bag info bags/avoid'])
    for add in (_add_summary, _add_plot, _add_csv, _add_play):
        add(commands)
    return parser


def _command(commands: argparse._SubParsersAction, name: str, handler: Callable[[argparse.Namespace], None],
             help_text: str, examples: list[str]) -> argparse.ArgumentParser:
    """A subcommand on a bag `path`, with its examples under its help."""
    sub = commands.add_parser(name, help=help_text, description=help_text,
                              formatter_class=argparse.RawDescriptionHelpFormatter,
                              epilog='examples:\n' + '\n'.join(f'  {e}' for e in examples))
    sub.add_argument('path', type=Path, help='bag folder or .mcap file')
    sub.set_defaults(handler=handler)
    return sub


def _add_namespace(sub: argparse.ArgumentParser) -> None:
    sub.add_argument('--namespace', help='only this robot, e.g. /epuck3 (default: every robot)')


def _add_summary(commands: argparse._SubParsersAction) -> None:
    summary = _command(commands, 'summary', _summary,
                       'distance, speed, closest approach, collisions, and what the run was (straight line, '
                       'spin, circle, rectangle, free motion) with that shape\'s figures; one row per robot',
                       ['bag summary bags/rectangle', 'bag summary --json bags/circle',
                        'bag summary bags/swarm --namespace /epuck3'])
    summary.add_argument('--json', action='store_true', help='machine-readable output')
    _add_namespace(summary)


def _add_plot(commands: argparse._SubParsersAction) -> None:
    plot = _command(commands, 'plot', _plot, 'a picture of the run: every robot\'s path over the arena, heading '
                                             'arrows, collisions, odometry from the start pose (1200x1000 px)',
                    ['bag plot bags/rectangle -o rectangle.png', 'bag plot bags/swarm -o swarm.svg'])
    plot.add_argument('-o', '--output', type=Path, required=True,
                      help=f'file to write; the extension picks the format ({", ".join(PLOT_FORMATS)})')
    _add_namespace(plot)


def _add_csv(commands: argparse._SubParsersAction) -> None:
    csv = _command(commands, 'csv', _csv, "one topic's messages as CSV: log_time, publish_time, then every field",
                   ['bag csv bags/avoid /odom -o odom.csv', 'bag csv bags/swarm /epuck3/odom | head'])
    csv.add_argument('topic', help='topic name, e.g. /odom or /epuck3/odom')
    csv.add_argument('-o', '--output', type=Path, help='CSV file to write (default: stdout)')
    csv.add_argument('--join-arrays', action='store_true',
                     help='one space-separated cell per array instead of one column per element')


def _add_play(commands: argparse._SubParsersAction) -> None:
    play = _command(commands, 'play', _play,
                    'publish a bag on its topics with their recorded QoS (latched ones transient local) and '
                    '/clock from the log time, as `ros2 bag play --clock` does; Ctrl-C stops. While paused, '
                    'Enter (on a terminal) or the std_srvs/Trigger services ~/resume, ~/pause, '
                    '~/toggle_paused of the `bag_player` node resume or pause. Before the first message it waits '
                    f'--wait seconds ({DEFAULT_WAIT:g} by default), saying so, for the graph to show the subscribers '
                    'already running (a node under Fast DDS\'s default profile announces itself every 3 s), then '
                    '(at most 10 s) until every one on a played topic is matched, so a recorder started first '
                    'misses nothing',
                    ['bag play bags/avoid', 'bag play bags/avoid --rate 5 --loop',
                     'bag play bags/avoid --start-paused --topics /ground_truth /world',
                     'bag play bags/avoid --wait 0 --rate 10',
                     'bag play bags/avoid --ros-args -r /odom:=/replayed/odom'])
    play.add_argument('--rate', type=_within(*RATES), default=1.0,
                      help=f'playback speed: 2 plays twice as fast (default 1; {RATES[0]:g} to {RATES[1]:g})')
    play.add_argument('--loop', action='store_true', help='start again at the end, until Ctrl-C')
    play.add_argument('--start-paused', action='store_true', help='wait for a resume before the first message')
    play.add_argument('--topics', nargs='+', metavar='TOPIC', help='only these topics (default: all)')
    play.add_argument('--clock', type=_within(*CLOCK_HZ), default=100.0, metavar='HZ',
                      help=f'/clock publications per wall second (default 100; {CLOCK_HZ[0]:g} to {CLOCK_HZ[1]:g})')
    play.add_argument('--wait', type=_within(*WAIT), default=DEFAULT_WAIT, metavar='S',
                      help=f'wall seconds from the start to look for the subscribers already running before the '
                           f'first message (default {DEFAULT_WAIT:g}; 0 plays at once, to whoever is matched)')


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    ros_args = []
    if '--ros-args' in argv:  # bag play passes them to rclpy, as ros2 run does
        split = argv.index('--ros-args')
        argv, ros_args = argv[:split], argv[split:]
    args = build_parser().parse_args(argv)
    args.ros_args = ros_args
    try:
        args.handler(args)
    except (BagError, CdrError) as error:
        refuse(f'bag {args.command}: error: {error}')
    except BrokenPipeError:  # `bag csv ... | head`: the reader has all it wants
        sys.stdout = open(os.devnull, 'w')
    except OSError as error:
        refuse(f'bag {args.command}: error: {error.filename or ""}: {error.strerror}')


if __name__ == '__main__':
    main()
