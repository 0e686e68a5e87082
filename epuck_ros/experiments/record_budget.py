"""How much disk a headless recording (`sweep --record`, `webots_controller --headless --record`) will take: said
before a large one starts, and refused, before anything is written, when the disk cannot hold it.

A headless bag holds the same messages every step for every robot, so it grows by a fixed amount per robot per
simulated second (about 82 KB) plus a fixed part per bag. Both are measured here, once per process, by recording
one short run twice (1 and 2 simulated seconds): the estimate follows whatever `recording` writes.
"""
from __future__ import annotations

import functools
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path

LARGE = 1 << 30
"""Bytes; a recording estimated above this is said before it starts."""


class RecordRefused(RuntimeError):
    """The disk cannot hold the recording (the message says the estimate and the free space), or its size could not
    be measured."""


@functools.lru_cache(maxsize=1)
def bag_growth() -> tuple[float, float]:
    """(bytes per robot per simulated second, bytes per bag), measured on two recordings of one robot."""
    from epuck_ros.experiments.trial import Trial, controller_from, run_trial
    sizes = []
    try:
        with tempfile.TemporaryDirectory() as folder:
            for seconds in (1.0, 2.0):
                bag = Path(folder) / str(seconds)
                (row,) = run_trial(Trial(controller_from('avoid'), duration=seconds, record=str(bag)))
                if row['error']:
                    raise RecordRefused(f'cannot measure what a recording takes: {row["error"]}')
                sizes.append(sum(file.stat().st_size for file in bag.rglob('*') if file.is_file()))
    except OSError as error:   # no room for the temporary folder, say
        raise RecordRefused(f'cannot measure what a recording takes: {error}') from None
    per_second = float(sizes[1] - sizes[0])
    return per_second, max(0.0, sizes[0] - per_second)


def estimate(runs: Iterable[tuple[int, float]]) -> float:
    """Bytes of the bags of `runs`, each (robots, simulated seconds)."""
    per_second, per_bag = bag_growth()
    return sum(per_bag + per_second * robots * seconds for robots, seconds in runs)


def check_room(folder: Path, size: float, what: str) -> str:
    """One line saying `size` (bytes) of `what` against the free space where `folder` is (or will be);
    RecordRefused when it does not fit."""
    existing = folder.resolve()
    while not existing.exists():
        existing = existing.parent
    free = shutil.disk_usage(existing).free
    line = f'{what}: about {_human(size)} ({_human(bag_growth()[0])} per robot per simulated second), ' \
           f'{_human(free)} free'
    if size > free:
        raise RecordRefused(f'{line}: not enough room on the disk')
    return line


def _human(size: float) -> str:
    for unit, scale in (('GB', 1e9), ('MB', 1e6), ('KB', 1e3)):
        if size >= scale:
            return f'{size / scale:.1f} {unit}'
    return f'{size:.0f} bytes'
