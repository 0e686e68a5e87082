"""bag: inspect recorded runs without ROS (info, summary, plot, csv).

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
from epuck_ros.bag.run_summary import RunData, RunSummary, format_summary, load_run, robot_namespaces, summarise

EXIT_ERROR = 2


def _info(args: argparse.Namespace) -> None:
    with Bag(args.path) as bag:
        print(format_info(bag))


def _runs(bag: Bag, namespace: str | None) -> list[tuple[RunData, RunSummary]]:
    namespaces = [namespace] if namespace else robot_namespaces(bag) or [None]
    runs = [load_run(bag, ns) for ns in namespaces]
    return [(run, summarise(run)) for run in runs]


def _summary(args: argparse.Namespace) -> None:
    with Bag(args.path) as bag:
        summaries = [summary for _, summary in _runs(bag, args.namespace)]
    if args.json:
        data = [s.to_dict() for s in summaries]
        print(json.dumps(data[0] if len(data) == 1 else data, indent=2))
    else:
        print('\n\n'.join(format_summary(s) for s in summaries))


def _plot(args: argparse.Namespace) -> None:
    from epuck_ros.bag.plot import plot_run  # matplotlib takes ~0.5 s to import: only when plotting
    with Bag(args.path) as bag:
        run, summary = _runs(bag, args.namespace)[0]
    plot_run(run, summary, args.output)
    print(f'wrote {args.output}')


def _csv(args: argparse.Namespace) -> None:
    with Bag(args.path) as bag:
        if args.output is None:
            export_csv(bag, args.topic, sys.stdout, args.join_arrays)
            return
        with open(args.output, 'w', newline='', encoding='utf-8') as output:
            rows = export_csv(bag, args.topic, output, args.join_arrays)
    print(f'wrote {rows} rows to {args.output}', file=sys.stderr)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog='bag', description=__doc__.split('\n\n')[0])
    commands = parser.add_subparsers(dest='command', required=True, metavar='COMMAND')

    def command(name: str, handler: Callable[[argparse.Namespace], None], help_text: str) -> argparse.ArgumentParser:
        sub = commands.add_parser(name, help=help_text, description=help_text)
        sub.add_argument('path', type=Path, help='bag folder or .mcap file')
        sub.set_defaults(handler=handler)
        return sub

    command('info', _info, 'what ros2 bag info prints, plus topic rates; instant from the MCAP summary')
    summary = command('summary', _summary, 'distance, speed, closest approach, collisions, course shape figures')
    summary.add_argument('--json', action='store_true', help='machine-readable output')
    plot = command('plot', _plot, 'PNG of the trajectory over the arena, coloured by time')
    plot.add_argument('-o', '--output', type=Path, required=True, help='PNG file to write')
    for sub in (summary, plot):
        sub.add_argument('--namespace', help='robot namespace (default: every robot; plot: the first)')
    csv = command('csv', _csv, "one topic's messages as CSV: log_time, publish_time, then every field")
    csv.add_argument('topic', help='topic name, e.g. /odom')
    csv.add_argument('-o', '--output', type=Path, help='CSV file to write (default: stdout)')
    csv.add_argument('--join-arrays', action='store_true',
                     help='one space-separated cell per array instead of one column per element')
    return parser


def main(argv: list[str] | None = None) -> None:
    args = build_parser().parse_args(argv)
    try:
        args.handler(args)
    except (BagError, CdrError) as error:
        print(f'bag {args.command}: error: {error}', file=sys.stderr)
        raise SystemExit(EXIT_ERROR)
    except BrokenPipeError:  # `bag csv ... | head`: the reader has all it wants
        sys.stdout = open(os.devnull, 'w')
    except OSError as error:
        print(f'bag {args.command}: error: {error.filename or ""}: {error.strerror}', file=sys.stderr)
        raise SystemExit(EXIT_ERROR)


if __name__ == '__main__':
    main()
