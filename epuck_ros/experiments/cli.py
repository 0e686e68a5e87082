"""`sweep SPEC.yaml -o OUT`: every trial of a spec, headless, on Dask; a table, a CSV and a picture.

OUT/trials.csv holds one row per robot per trial (figures from `RunTally`, the code of `bag summary`; floats in
round-trip precision), each trial's rows written as it finishes (`table`), so `--resume` runs only the trials not
in it yet. A trial that fails is a row per robot with its error and the sweep goes on (exit 1 at the end); a bad
spec, option or folder, an unusable scheduler or a recording the disk cannot hold is one line and exit 2 before any
trial, and before OUT is touched; Ctrl-C or SIGTERM keeps what is done and exits 130 or 143.
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

from epuck_ros import untrusted_yaml
from epuck_ros.exit_codes import EXIT_FAILED, ignore_ctrl_c_at_exit, refuse
from epuck_ros.experiments.cluster import (
    ClusterError, add_cluster_arguments, check_cluster_arguments, default_workers, open_client)
from epuck_ros.experiments.interruption import exit_code, interrupts_ignored, terminate_as_interrupt
from epuck_ros.experiments.output import OutputError, OutputFolder
from epuck_ros.experiments.record_budget import RecordRefused, check_room, estimate
from epuck_ros.experiments.spec import Spec, SpecError, load_spec
from epuck_ros.experiments.table import Row, Table, TableError
from epuck_ros.experiments.trial import Trial, failed_rows, run_trial

PROGRESS_PERIOD = 0.5
"""Wall seconds between two progress lines at most."""


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog='sweep', description='Run every combination of a spec (controllers x worlds x robot counts x seeds) '
        'headless on the pure core, on Dask: OUT/trials.csv (a row per robot per trial), a summary table per '
        'controller and world, OUT/sweep.png. A trial gives the ground truth of `bringup ... --lockstep '
        '--real-time-factor 0` with the same seed, to the bit. Exit code: 0; 1 when a trial failed (its rows say '
        'why); 2 for a bad spec, option or output folder, an unusable scheduler or a recording the disk cannot '
        'hold, before any trial; 130 (Ctrl-C) or 143 (SIGTERM) when interrupted, the trials done kept.',
        epilog='example: sweep epuck_ros/experiments/examples/avoid_seeds.yaml -o sweep_out --workers 2')
    parser.add_argument('spec', type=Path, help='the spec (YAML); its relative paths are relative to it')
    parser.add_argument('-o', '--output', type=Path, required=True,
                        help='output folder (made if missing; one sweep at a time)')
    add_cluster_arguments(parser, 'every trial')
    parser.add_argument('--resume', action='store_true',
                        help='run only the trials OUT/trials.csv does not hold in full (failed ones again); refused '
                             'if it holds rows of another or an edited spec')
    parser.add_argument('--record', action='store_true',
                        help='also write each trial as a rosbag2 MCAP bag, OUT/bags/<trial>/, readable by `bag` and '
                             'rosbags (the workers write there: with --scheduler, OUT must be on a shared file '
                             'system); the size is estimated first, and refused if the disk cannot hold it')
    args = parser.parse_args(argv)
    check_cluster_arguments(parser, args)
    return args


def main(argv: list[str] | None = None) -> None:
    ignore_ctrl_c_at_exit()
    args = parse_args(sys.argv[1:] if argv is None else argv)
    try:
        with terminate_as_interrupt():
            sweep(args)
    except KeyboardInterrupt as interruption:   # before any trial (the table is never left half written)
        print('\n[sweep] interrupted before any trial ran', file=sys.stderr)
        raise SystemExit(exit_code(interruption)) from None


def sweep(args: argparse.Namespace) -> None:
    """Run the spec's trials, then write the sorted table, the summary and the picture."""
    try:
        spec = load_spec(args.spec)
        folder = OutputFolder(args.output)
        folder.lock()   # if it exists: nothing is written before the cluster answers
        table = Table(folder, spec.trials)
        done = table.done() if args.resume else {}
        todo = _todo(args, spec, done)
    except (SpecError, OutputError, TableError, RecordRefused) as error:
        _refuse(error)
    interrupted: KeyboardInterrupt | None = None
    started = False
    try:
        workers = _local_workers(args.workers, len(todo))   # none: no cluster, nothing to run
        with open_client(workers, args.scheduler if todo else None, allowed_failures=0) as client:
            folder.make()
            table.start(row for rows in done.values() for row in rows)
            started = True
            print(f'[sweep] {len(spec.trials)} trials ({len(done)} done before), {_where(args, client, workers)}',
                  file=sys.stderr, flush=True)
            progress = Progress(len(todo), _slots(client))
            try:
                for rows in results(client, todo):
                    table.append(rows)
                    progress.show(rows)
            finally:
                table.close()
    except (ClusterError, OutputError) as error:
        _refuse(error)
    except KeyboardInterrupt as interruption:   # the rows written so far are kept, --resume runs the rest
        if not started:   # OUT as it was (a table there may be another sweep's)
            raise
        interrupted = interruption
    try:
        with interrupts_ignored():
            _finish(args, spec, table, folder, interrupted)
    except OutputError as error:   # the disk filled up, say
        print(f'sweep: {error}', file=sys.stderr)
        raise SystemExit(EXIT_FAILED) from None


def _refuse(error: Exception) -> None:
    refuse(f'sweep: {error}')


def _todo(args: argparse.Namespace, spec: Spec, done: dict[int, list[Row]]) -> list[Trial]:
    """The trials to run (each with its bag folder under --record, the size of the bags checked first)."""
    todo = [trial for trial in spec.trials if trial.index not in done]
    if args.record and todo:
        size = estimate((spec.robot_count(trial), trial.duration) for trial in todo)
        print(f'[sweep] {check_room(args.output, size, f"--record of {len(todo)} trials")}', file=sys.stderr)
        bags = args.output.resolve() / 'bags'
        todo = [replace(trial, record=str(bags / str(trial.index))) for trial in todo]
    return todo


def _local_workers(requested: int | None, trials: int) -> int:
    """A local cluster's workers: as asked (default one per core), never more than the trials to run."""
    return min(default_workers() if requested is None else requested, trials)


def _finish(args: argparse.Namespace, spec: Spec, table: Table, folder: OutputFolder,
            interrupted: KeyboardInterrupt | None) -> None:
    """The table sorted, the summary and the picture; the exit code."""
    rows = sorted(table.rows(), key=lambda row: (int(row['trial']), row['robot']))
    table.replace(rows)
    print(summary_table(rows))
    from epuck_ros.experiments.picture import draw_sweep
    picture = folder.replace('sweep.png', lambda out: draw_sweep(rows, out))
    if interrupted is not None:
        ran = len({row['trial'] for row in rows if not row['error']})
        print(f'\n[sweep] interrupted with {ran} of {len(spec.trials)} trials done in {table.path}; the same '
              'command with --resume runs the others', file=sys.stderr)
        raise SystemExit(exit_code(interrupted))
    failed = sorted({int(row['trial']) for row in rows if row['error']})
    print(f'[sweep] wrote {table.path} and {picture}' +
          (f'; {len(failed)} trials failed (their rows say why)' if failed else ''), file=sys.stderr)
    if failed:
        raise SystemExit(EXIT_FAILED)


def _where(args: argparse.Namespace, client: object | None, workers: int) -> str:
    if args.scheduler and client is not None:
        return f'on the Dask cluster at {args.scheduler} ({_slots(client)} workers now)'
    if client is None:
        return 'in this process'
    asked = default_workers() if args.workers is None else args.workers
    return f'on a local Dask cluster of {workers} workers' + (' (one per trial to run)' if workers < asked else '')


def _slots(client: object | None) -> int:
    """How many trials run at once."""
    return 1 if client is None else max(1, len(client.scheduler_info()['workers']))


def results(client: object | None, trials: list[Trial]) -> Iterator[list[dict]]:
    """Each trial's rows as it finishes (any order). Dask gives up on a task whose worker died under it (KilledWorker:
    at once on the sweep's local cluster, `allowed_failures=0`; else after a few deaths), also on one that only
    shared a worker with a trial that kills its worker's process: such trials run again at the end, each alone on
    the cluster, and one that fails again is its own error rows. (Dask's own retries killed the worker of such a
    trial four times, and a local cluster's nanny did not start the last of them again: the sweep waited for ever.)"""
    if client is None:
        for trial in trials:
            yield run_trial(trial)
        return
    from dask.distributed import as_completed
    futures = client.map(run_trial, trials, pure=True)
    by_key = {future.key: trial for future, trial in zip(futures, trials)}
    suspects = []
    for future in as_completed(futures):
        try:
            yield future.result()
        except Exception:  # noqa: BLE001 - KilledWorker above all; the trial runs again alone
            suspects.append(by_key[future.key])
        future.release()
    for trial in suspects:
        try:
            yield client.submit(run_trial, trial, pure=False).result()
        except Exception as error:  # noqa: BLE001 - the trial's result
            yield failed_rows(trial, _lost(error))


def _lost(error: Exception) -> str:
    """A trial Dask could not run, in one line."""
    if type(error).__name__ == 'KilledWorker':
        return 'its Dask worker died each time Dask ran the trial, alone on the cluster too (KilledWorker): the ' \
               'trial ends its worker\'s process'
    return f'Dask could not run the trial: {type(error).__name__}: {untrusted_yaml.cut(str(error), 200)}'


class Progress:
    """One progress line on stderr: done/total, failures, and the time left, from the wall time of the trials done
    and how many run at once (not from the time since the start, which holds the cluster's start-up)."""

    def __init__(self, total: int, slots: int, clock: object = time.monotonic) -> None:
        self.total, self.slots, self._clock = total, slots, clock
        self.done = self.failures = 0
        self._wall = 0.0
        self._said = -PROGRESS_PERIOD

    def show(self, rows: list[dict]) -> None:
        self.done += 1
        self.failures += any(row['error'] for row in rows)
        wall = max((float(row['wall_s']) for row in rows), default=math.nan)
        self._wall += wall if math.isfinite(wall) else 0.0
        now = self._clock()
        if now - self._said < PROGRESS_PERIOD and self.done < self.total:
            return
        self._said = now
        print(self.line(), end='\n' if self.done == self.total else '\r', file=sys.stderr, flush=True)

    def line(self) -> str:
        left = self.total - self.done
        eta = self._wall / self.done * left / min(self.slots, left) if left else 0.0
        return f'[sweep] {self.done}/{self.total} trials, {self.failures} failed, ETA {eta:.0f} s   '


def summary_table(rows: list[Row]) -> str:
    """Mean and spread (standard deviation) of distance and contacts per controller, world and robot count."""
    groups: dict[tuple[str, str, str], list[Row]] = {}
    for row in rows:
        if not row['error']:
            groups.setdefault((row['controller'], row['world'], row['robots']), []).append(row)
    wide = max([len('controller'), *(len(controller) for controller, _, _ in groups)])
    world_wide = max([len('world'), *(len(world) for _, world, _ in groups)])
    header = f'{"controller":{wide}} {"world":{world_wide}} {"robots":>6} {"runs":>5} {"distance m":>16} ' \
             f'{"contacts":>14}'
    lines = [header, '-' * len(header)]
    for (controller, world, robots), members in sorted(groups.items()):
        distance = [float(row['distance_m']) for row in members]
        contacts = [float(row['contacts_obstacles']) + float(row['contacts_robots']) for row in members]
        lines.append(f'{controller:{wide}} {world:{world_wide}} {robots:>6} {len(members):>5} '
                     f'{_mean_spread(distance, 3):>16} {_mean_spread(contacts, 2):>14}')
    return '\n'.join(lines)


def _mean_spread(values: list[float], digits: int) -> str:
    spread = statistics.stdev(values) if len(values) > 1 else 0.0
    return f'{statistics.fmean(values):.{digits}f} ± {spread:.{digits}f}' if values else 'nan'


if __name__ == '__main__':
    main()
