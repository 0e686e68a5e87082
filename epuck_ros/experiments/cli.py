"""`sweep SPEC.yaml -o OUT`: every trial of a spec, headless, on Dask; a table, a CSV and a picture.

OUT/trials.csv holds one row per robot per trial (figures from `RunTally`, the code of `bag summary`; floats in
round-trip precision), written as trials finish, so `--resume` runs only the trials not in it yet. A trial that
fails is a row with its error and the sweep goes on (exit 1 at the end); a bad spec or an unreachable scheduler
is one line and exit 2 before any trial.
"""
from __future__ import annotations

import argparse
import csv
import signal
import statistics
import sys
import time
from collections.abc import Iterable, Iterator
from dataclasses import replace
from pathlib import Path

from epuck_ros.experiments.cluster import (
    ClusterError, add_cluster_arguments, check_cluster_arguments, default_workers, open_client)
from epuck_ros.experiments.spec import SpecError, load_spec
from epuck_ros.experiments.trial import COLUMNS, Trial, run_trial

EXIT_FAILED, EXIT_BAD_INPUT = 1, 2
PROGRESS_PERIOD = 0.5
"""Wall seconds between two progress lines at most."""


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='sweep', description='Run every combination of a spec (controllers x worlds x robot counts x seeds) '
        'headless on the pure core, on Dask: OUT/trials.csv (a row per robot per trial), a summary table per '
        'controller and world, OUT/sweep.png. A trial gives the ground truth of `bringup ... --lockstep '
        '--real-time-factor 0` with the same seed, to the bit. Exit code: 0; 1 when a trial failed (its row says '
        'why); 2 for a bad spec or option, or an unreachable scheduler, before any trial.',
        epilog='example: sweep epuck_ros/experiments/examples/avoid_seeds.yaml -o sweep_out --workers 2')
    parser.add_argument('spec', type=Path, help='the spec (YAML); its relative paths are relative to it')
    parser.add_argument('-o', '--output', type=Path, required=True, help='output folder (made if missing)')
    add_cluster_arguments(parser, 'every trial')
    parser.add_argument('--resume', action='store_true', help='skip the trials already in OUT/trials.csv')
    parser.add_argument('--record', action='store_true',
                        help='also write each trial as a rosbag2 MCAP bag, OUT/bags/<trial>/, readable by `bag` and '
                             'rosbags (the workers write there: with --scheduler, OUT must be on a shared file system)')
    args = parser.parse_args(argv)
    check_cluster_arguments(parser, args)
    return args


def main(argv: list[str] | None = None) -> None:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        sweep(args)
    except KeyboardInterrupt:   # before the trials (the table, replaced whole, is never left half written)
        print('\n[sweep] interrupted', file=sys.stderr)


def sweep(args: argparse.Namespace) -> None:
    """Run the spec's trials, then write the sorted table, the summary and the picture."""
    try:
        spec = load_spec(args.spec)
    except SpecError as error:
        print(f'sweep: {error}', file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT) from None
    table, done, todo = _pending(args, spec.trials)
    interrupted = False
    try:
        with open_client(args.workers, args.scheduler) as client, open(table, 'a', newline='') as out:
            print(f'[sweep] {len(spec.trials)} trials ({len(done)} done before), {_where(args)}', file=sys.stderr,
                  flush=True)
            writer = csv.DictWriter(out, COLUMNS)
            if out.tell() == 0:
                writer.writeheader()
            failures = 0
            for finished, rows in enumerate(results(client, todo), 1):
                writer.writerows(rows)
                out.flush()
                failures += any(row['error'] for row in rows)
                progress.show(finished, len(todo), failures)
        _finish_uninterrupted()
    except ClusterError as error:
        print(f'sweep: {error}', file=sys.stderr)
        raise SystemExit(EXIT_BAD_INPUT) from None
    except KeyboardInterrupt:   # Ctrl-C: the rows written so far are kept, --resume runs the rest
        interrupted = True
        _finish_uninterrupted()
    rows = sorted(read_rows(table), key=lambda row: (int(row['trial']), row['robot']))
    write_rows(table, rows)
    print(summary_table(rows))
    from epuck_ros.experiments.picture import draw_sweep
    draw_sweep(rows, args.output / 'sweep.png')
    if interrupted:
        print(f'\n[sweep] interrupted with {len({row["trial"] for row in rows})} of {len(spec.trials)} trials in '
              f'{table}; the same command with --resume runs the others', file=sys.stderr)
        return
    failed = sorted({int(row['trial']) for row in rows if row['error']})
    print(f'[sweep] wrote {table} and {args.output / "sweep.png"}' +
          (f'; {len(failed)} trials failed (their rows say why)' if failed else ''), file=sys.stderr)
    if failed:
        raise SystemExit(EXIT_FAILED)


def _pending(args: argparse.Namespace, trials: Iterable[Trial]) -> tuple[Path, set[int], list[Trial]]:
    """OUT/trials.csv (emptied, or with --resume cut to its complete rows), the trials it holds, and the trials
    left to run (each with its bag folder under --record)."""
    args.output.mkdir(parents=True, exist_ok=True)
    table = args.output / 'trials.csv'
    if args.resume:   # the complete rows only: an interrupted sweep may have left a line cut short
        write_rows(table, read_rows(table))
    else:
        table.unlink(missing_ok=True)
    done = {int(row['trial']) for row in read_rows(table)}
    todo = [trial for trial in trials if trial.index not in done]
    if args.record:
        bags = args.output.resolve() / 'bags'
        todo = [replace(trial, record=str(bags / str(trial.index))) for trial in todo]
    return table, done, todo


def _finish_uninterrupted() -> None:
    """From here on Ctrl-C is ignored: the table, the summary and the picture take a moment, and a Ctrl-C during the
    interpreter's exit would end the process with SIGINT's status instead of the sweep's."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _where(args: argparse.Namespace) -> str:
    if args.scheduler:
        return f'on the Dask cluster at {args.scheduler}'
    if args.workers == 0:
        return 'in this process'
    return f'on a local Dask cluster of {args.workers or default_workers()} workers'


def results(client: object | None, trials: list[Trial]) -> Iterator[list[dict]]:
    """Each trial's rows as it finishes (any order)."""
    if client is None:
        for trial in trials:
            yield run_trial(trial)
        return
    from dask.distributed import as_completed
    futures = client.map(run_trial, trials, pure=True)
    for future in as_completed(futures):
        yield future.result()


class _Progress:
    """One progress line on stderr: done/total, failures, and the time left at the pace so far."""

    def __init__(self) -> None:
        self._began = time.monotonic()
        self._said = 0.0

    def show(self, done: int, total: int, failures: int) -> None:
        now = time.monotonic()
        if now - self._said < PROGRESS_PERIOD and done < total:
            return
        self._said = now
        left = (now - self._began) / done * (total - done)
        end = '\n' if done == total else '\r'
        print(f'[sweep] {done}/{total} trials, {failures} failed, ETA {left:.0f} s   ', end=end, file=sys.stderr,
              flush=True)


progress = _Progress()


def read_rows(table: Path) -> list[dict]:
    """The complete rows of `table` (a line cut short by an interruption has missing fields: dropped)."""
    if not table.exists():
        return []
    with open(table, newline='') as stream:
        return [row for row in csv.DictReader(stream) if None not in row.values() and None not in row]


def write_rows(table: Path, rows: Iterable[dict]) -> None:
    partial = table.with_suffix('.csv.partial')
    with open(partial, 'w', newline='') as out:
        writer = csv.DictWriter(out, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    partial.replace(table)


def summary_table(rows: list[dict]) -> str:
    """Mean and spread (standard deviation) of distance and contacts per controller, world and robot count."""
    groups: dict[tuple[str, str, str], list[dict]] = {}
    for row in rows:
        if not row['error']:
            groups.setdefault((row['controller'], row['world'], row['robots']), []).append(row)
    header = f'{"controller":24} {"world":20} {"robots":>6} {"runs":>5} {"distance m":>16} {"contacts":>14}'
    lines = [header, '-' * len(header)]
    for (controller, world, robots), members in sorted(groups.items()):
        distance = [float(row['distance_m']) for row in members]
        contacts = [float(row['contacts_obstacles']) + float(row['contacts_robots']) for row in members]
        lines.append(f'{_fit(controller, 24):24} {_fit(world, 20):20} {robots:>6} {len(members):>5} '
                     f'{_mean_spread(distance, 3):>16} {_mean_spread(contacts, 2):>14}')
    return '\n'.join(lines)


def _fit(label: str, width: int) -> str:
    """A label cut to `width` characters from the front: a script's or world's path ends with its name."""
    return label if len(label) <= width else '…' + label[-(width - 1):]


def _mean_spread(values: list[float], digits: int) -> str:
    spread = statistics.stdev(values) if len(values) > 1 else 0.0
    return f'{statistics.fmean(values):.{digits}f} ± {spread:.{digits}f}' if values else 'nan'


if __name__ == '__main__':
    main()
