"""OUT/trials.csv: a sweep's rows, each trial's rows appended in one write as it finishes, and what `--resume` may
keep of them.

A row says which trial it is by its number and its key (`Trial.key`: a hash of everything its rows depend on), so
a table is resumed only by the sweep that wrote it: a row of another spec, or of an edited one, is refused with
one line, as is a row that is not a sweep's (a foreign header, `trial` = -7, `distance_m` = lots). A trial counts
as done when it has one row per robot, none with an error: a failed trial and one cut short run again. The line
being written when a sweep was killed (no line end yet) is dropped.
"""
from __future__ import annotations

import csv
import io
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from epuck_ros.experiments.output import OutputFolder
from epuck_ros.experiments.trial import COLUMNS, Trial
from epuck_ros.untrusted_file import FileMissing, FileProblem, open_regular

NAME = 'trials.csv'
NUMBERS = ('distance_m', 'final_x', 'final_y', 'final_yaw', 'sim_time', 'wall_s')
COUNTS = ('contacts_obstacles', 'contacts_robots')
RESUME_HINT = '--resume cannot go on from it: run without --resume to start over, or into another folder'
Row = dict[str, str]


class TableError(ValueError):
    """The table cannot be resumed; the message names the file, the line and the column."""


class Table:
    """The trials.csv of one sweep of `trials` (indexed by their number) in `folder`."""

    def __init__(self, folder: OutputFolder, trials: Sequence[Trial]) -> None:
        self.folder, self.trials = folder, trials
        self.path = folder.path / NAME
        self._fd: int | None = None

    def done(self) -> dict[int, list[Row]]:
        """The rows of each trial the table holds in full, by trial number; TableError if it holds anything that
        is not a row of these trials."""
        by_trial: dict[int, list[Row]] = {}
        for row in self.rows():
            by_trial.setdefault(int(row['trial']), []).append(row)
        return {trial: rows for trial, rows in by_trial.items() if _complete(rows)}

    def rows(self) -> list[Row]:
        """Every row, each checked against its trial (TableError); none if there is no table."""
        try:
            with open_regular(self.path) as raw:
                records = _records(raw, self.path)
        except FileMissing:
            return []
        except FileProblem as problem:
            raise TableError(f'{self.path}: {problem}') from None
        if not records:
            return []
        header_line, header = records[0]
        if tuple(header) != COLUMNS:
            raise TableError(f'{self.path}: not the table of a sweep of this version (its first line is not '
                             f'{",".join(COLUMNS)}); {RESUME_HINT}')
        rows = []
        for line, record in records[1:]:
            if len(record) != len(COLUMNS):
                raise TableError(f'{self.path}, line {line}: {len(record)} fields, not {len(COLUMNS)}; {RESUME_HINT}')
            row = dict(zip(COLUMNS, record))
            problem = self._problem(row)
            if problem:
                raise TableError(f'{self.path}, line {line}: {problem}; {RESUME_HINT}')
            rows.append(row)
        return rows

    def _problem(self, row: Row) -> str:
        """What makes `row` no row of this sweep's trials ('' if nothing)."""
        number = row['trial']
        if not (number.isascii() and number.isdigit()) or int(number) >= len(self.trials):
            return f'trial {number!r}: not a trial of this sweep (0 to {len(self.trials) - 1})'
        trial = self.trials[int(number)]
        if (row['trial_key'], row['controller'], row['world'], row['seed']) != \
                (trial.key, trial.controller.label, trial.world_label, str(trial.seed)):
            return (f'trial {number} there is not trial {number} of this spec (another spec, or the spec or a file '
                    'it names has changed since)')
        for column in NUMBERS:
            try:
                float(row[column])
            except ValueError:
                return f'{column} {row[column]!r}: not a number'
        for column in ('robots', *COUNTS):
            if not (row[column].isascii() and row[column].isdigit()) and not (row['error'] and row[column] == ''):
                return f'{column} {row[column]!r}: not a count'
        return ''

    def start(self, kept: Iterable[Row]) -> None:
        """The table anew: its header and the rows `kept`, replacing whatever was there; rows are appended next."""
        self.replace(kept)
        try:
            self._fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        except OSError as error:
            raise self.folder.fail(f'cannot write {NAME}: {error.strerror}') from None

    def append(self, rows: list[dict]) -> None:
        """A trial's rows, in one write at the end of the table (a reader never sees half of a trial, unless the
        machine dies mid-write: `done` then sees a trial cut short)."""
        data = _csv_text([[row[column] for column in COLUMNS] for row in rows]).encode()
        try:
            while data:
                data = data[os.write(self._fd, data):]
        except OSError as error:   # the disk full, say
            raise self.folder.fail(f'cannot write {NAME}: {error.strerror}') from None

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def replace(self, rows: Iterable[Row]) -> None:
        """The table as `rows`, written whole beside it and renamed over it."""
        text = _csv_text([list(COLUMNS), *([row[column] for column in COLUMNS] for row in rows)])
        self.folder.replace(NAME, lambda out: out.write(text.encode()))


def _records(raw: io.BufferedIOBase, path: Path) -> list[tuple[int, list[str]]]:
    """The CSV records of `raw` with their line numbers; the last one dropped if it has no line end yet."""
    size = os.fstat(raw.fileno()).st_size
    if size == 0:
        return []
    raw.seek(size - 1)
    whole = raw.read(1) == b'\n'
    raw.seek(0)
    reader = csv.reader(io.TextIOWrapper(raw, encoding='utf-8', errors='strict', newline=''))
    records: list[tuple[int, list[str]]] = []
    try:
        for record in reader:
            records.append((reader.line_num, record))
    except csv.Error as error:
        if whole:
            raise TableError(f'{path}, line {reader.line_num}: {error}; {RESUME_HINT}') from None
        return records   # the record being written when the sweep ended, cut short inside a quoted field
    except UnicodeDecodeError:
        raise TableError(f'{path}: not UTF-8 text; {RESUME_HINT}') from None
    return records if whole else records[:-1]


def _complete(rows: list[Row]) -> bool:
    """A trial's rows say it ran: one per robot, none with an error."""
    counts = {row['robots'] for row in rows}
    return not any(row['error'] for row in rows) and len(counts) == 1 and \
        len({row['robot'] for row in rows}) == len(rows) == int(counts.pop())


def _csv_text(records: Iterable[Sequence[object]]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer).writerows(records)
    return buffer.getvalue()
