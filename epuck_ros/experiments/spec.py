"""A sweep's spec (YAML, `../shared/design.md` "Experiments"): every combination of controllers x worlds x robot
counts x seeds, each a `Trial`. Bad input is one `SpecError` line naming the file and field, before any trial runs.

```yaml
controllers: [avoid, {behaviour: avoid, parameters: {cruise_speed: 0.4}}, {script: my_controller.py}]
worlds: [default, my_world.yaml]   # relative to the spec file; 'default' = the built-in world
robots: [1, 5]                      # 0 or 1: the world's own robots; N > 1: N placed as `sim -p robots:=N`
seeds: {first: 0, count: 10}        # or a list
duration: 60                        # simulated seconds per trial
noise: true
time_limit: 600                     # wall seconds a trial with a script may take before it is killed
memory_limit: 2048                  # megabytes (resident) a trial with a script may take before it is killed
```
"""
from __future__ import annotations

import difflib
import hashlib
import itertools
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from epuck_ros import untrusted_yaml
from epuck_ros.behaviours import BEHAVIOURS, ConfigError
from epuck_ros.behaviours.base import describe
from epuck_ros.experiments.trial import (DEFAULT_MEMORY_LIMIT, DEFAULT_TIME_LIMIT, DEFAULT_WORLD, Controller, Script,
                                         Trial, controller_from)
from epuck_ros.simulation import MAX_SEED
from epuck_ros.untrusted_file import FileProblem, read_bounded
from epuck_ros.webots.script_file import read_script
from epuck_ros.world import MAX_FILE_BYTES as WORLD_FILE_BYTES
from epuck_ros.world import World, WorldError, default_world, load_world, place_robots

MAX_TRIALS = 100_000
"""Trials in one spec at most (a typo such as `count: 1e9` would otherwise queue a billion)."""
MAX_DURATION = 3600.0
"""Simulated seconds per trial at most."""
MAX_ROBOTS = 10_000
MAX_FILE_BYTES = 1 << 20
"""A spec larger than this is refused unread."""
MAX_TIME_LIMIT = 86_400.0
MAX_MEMORY_LIMIT = float(1 << 20)
"""Megabytes (a tebibyte): a spec's `memory_limit` at most."""
KEY_LENGTH = 16
"""Hex digits of a trial's key (64 bits of SHA-256): no two trials of any sweep will share one."""
KEYS = ('controllers', 'worlds', 'robots', 'seeds', 'duration', 'noise', 'time_limit', 'memory_limit')


class SpecError(ValueError):
    """The spec cannot be run; the message names the file and field."""


@dataclass(frozen=True)
class Spec:
    path: Path
    trials: tuple[Trial, ...]
    world_robots: dict[str, int]
    """The number of robots of each world's own (by `Trial.world`)."""

    def robot_count(self, trial: Trial) -> int:
        """How many robots `trial` runs."""
        return trial.robots if trial.robots > 1 else self.world_robots[trial.world]


def load_spec(path: Path) -> Spec:
    """The spec at `path`, every field checked (SpecError), every trial made."""
    try:
        text = read_bounded(path, MAX_FILE_BYTES).decode('utf-8')
    except FileProblem as problem:
        raise SpecError(f'{path}: {problem}') from None
    except UnicodeDecodeError as error:
        raise SpecError(f'{path}: not UTF-8 text (byte {error.start})') from None
    try:
        data = untrusted_yaml.load(text, 8)
    except untrusted_yaml.UntrustedYamlError as error:
        raise SpecError(f'{path}: {error}') from None
    fields = _Fields(path)
    trials = tuple(_trials(fields, data))
    return Spec(path, trials, {world.path: len(world.world.robots) for world in fields.worlds.values()})


class _Fields:
    """Typed access to the spec's fields; each failure a SpecError naming the file and field."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.worlds: dict[str, _World] = {}
        """Each world file the spec names, by its resolved path: loaded once."""

    def fail(self, field: str, problem: str) -> SpecError:
        return SpecError(f'{self.path}: {field}: {problem}')

    def items(self, value: Any, field: str) -> list[Any]:
        if not isinstance(value, list) or not value:
            raise self.fail(field, f'expected a non-empty list, got {untrusted_yaml.cut(repr(value), 60)}')
        return value

    def number(self, value: Any, field: str, high: float, unit: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value <= high:
            raise self.fail(field, f'expected {unit} above 0 and at most {high:g}, '
                                   f'got {untrusted_yaml.cut(repr(value), 60)}')
        return float(value)

    def integer(self, value: Any, field: str, low: int, high: int) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise self.fail(field, f'expected a whole number from {low} to {high}, '
                                   f'got {untrusted_yaml.cut(repr(value), 60)}')
        return value


def _trials(fields: _Fields, data: Any) -> list[Trial]:
    if not isinstance(data, dict):
        raise fields.fail('<top level>', f'expected a mapping with keys {", ".join(KEYS)}')
    for key in data:
        if key not in KEYS:
            close = difflib.get_close_matches(str(key), KEYS, n=1)
            hint = f'did you mean {close[0]}?' if close else f'expected: {", ".join(KEYS)}'
            raise fields.fail(str(key), f'unknown key ({hint})')
    for key in ('controllers', 'seeds', 'duration'):
        if key not in data:
            raise fields.fail(key, 'missing')
    controllers = _labelled([_controller(fields, item, f'controllers[{i}]')
                             for i, item in enumerate(fields.items(data['controllers'], 'controllers'))])
    worlds = _labelled_worlds([_world(fields, item, f'worlds[{i}]')
                               for i, item in enumerate(fields.items(data.get('worlds', [DEFAULT_WORLD]), 'worlds'))])
    robots = [fields.integer(item, f'robots[{i}]', 0, MAX_ROBOTS)
              for i, item in enumerate(fields.items(data.get('robots', [1]), 'robots'))]
    seeds = _seeds(fields, data['seeds'])
    duration = fields.number(data['duration'], 'duration', MAX_DURATION, 'simulated seconds')
    noise = data.get('noise', True)
    if not isinstance(noise, bool):
        raise fields.fail('noise', f'expected true or false, got {untrusted_yaml.cut(repr(noise), 60)}')
    limit = fields.number(data.get('time_limit', DEFAULT_TIME_LIMIT), 'time_limit', MAX_TIME_LIMIT, 'wall seconds')
    memory = fields.number(data.get('memory_limit', DEFAULT_MEMORY_LIMIT), 'memory_limit', MAX_MEMORY_LIMIT,
                           'megabytes')
    count = len(controllers) * len(worlds) * len(robots) * len(seeds)
    if count > MAX_TRIALS:
        raise fields.fail('<top level>', f'{count} trials, more than {MAX_TRIALS} in one spec: split it')
    for world, robot_count in itertools.product({world.path: world for world in worlds}.values(), robots):
        if robot_count > 1:   # placement fails before any trial
            try:
                place_robots(world.world, robot_count, 0)
            except WorldError as error:
                raise fields.fail('robots', f'{robot_count} in {world.label}: {error}') from None
    return [Trial(controller, world.path, robot_count if robot_count > 1 else 0, seed, float(duration), noise, index,
                  world.label, float(limit), memory_limit=float(memory),
                  key=_key(controller, world, robot_count if robot_count > 1 else 0, seed, float(duration), noise))
            for index, (controller, world, robot_count, seed)
            in enumerate(itertools.product(controllers, worlds, robots, seeds))]


def _controller(fields: _Fields, item: Any, field: str) -> Controller | Script:
    if isinstance(item, dict) and 'script' in item:
        return _script(fields, item, field)
    if isinstance(item, str):
        name, parameters = item, {}
    elif isinstance(item, dict) and set(item) <= {'behaviour', 'parameters'} and 'behaviour' in item:
        name, parameters = item['behaviour'], item.get('parameters') or {}
    elif isinstance(item, dict) and 'behaviour' in item:
        unknown = sorted(str(key) for key in item if key not in ('behaviour', 'parameters'))
        raise fields.fail(f'{field}.{unknown[0]}', 'unknown key (expected: behaviour, parameters)')
    else:
        raise fields.fail(field, 'expected a behaviour name, {behaviour: NAME, parameters: {...}} or '
                                 '{script: PATH}')
    if not isinstance(name, str):
        raise fields.fail(f'{field}.behaviour', f'expected a behaviour name, got {untrusted_yaml.cut(repr(name), 60)}')
    if name not in BEHAVIOURS:
        close = difflib.get_close_matches(str(name), list(BEHAVIOURS), n=1)
        hint = f'did you mean {close[0]}?' if close else f'known: {", ".join(BEHAVIOURS)}'
        raise fields.fail(field, f'unknown behaviour {untrusted_yaml.cut(repr(name), 40)} ({hint})')
    if not isinstance(parameters, dict):
        raise fields.fail(f'{field}.parameters', 'expected a mapping of setting: value')
    known = [setting for setting, *_ in describe(BEHAVIOURS[name].defaults)]
    for setting in parameters:
        if setting not in known:
            close = difflib.get_close_matches(str(setting), known, n=1)
            hint = f'did you mean {close[0]}?' if close else f'known: {", ".join(known)}'
            raise fields.fail(f'{field}.parameters.{setting}', f'{name} has no such setting ({hint})')
    try:
        return controller_from(name, parameters)
    except (ConfigError, TypeError, ValueError) as error:
        raise fields.fail(f'{field}.parameters', str(error)) from None


def _script(fields: _Fields, item: dict, field: str) -> Script:
    """A Webots-style script: it must exist and compile (a syntax error would otherwise fail every trial)."""
    if set(item) != {'script'}:
        unknown = sorted(str(key) for key in item if key != 'script')
        raise fields.fail(f'{field}.{unknown[0]}', 'unknown key (a script controller is {script: PATH})')
    name = item['script']
    if not isinstance(name, str) or not name:
        raise fields.fail(f'{field}.script', f'expected the path of a Python script, got '
                                             f'{untrusted_yaml.cut(repr(name), 60)}')
    try:
        source = read_script(fields.path.parent / name)
    except FileProblem as problem:
        shown = name if name.isprintable() else repr(name)
        raise fields.fail(f'{field}.script', f'{untrusted_yaml.cut(shown, 80)}: {problem}') from None
    path = (fields.path.parent / name).resolve()
    try:
        compile(source, str(path), 'exec')
    except (SyntaxError, ValueError) as error:
        where = f' (line {error.lineno})' if getattr(error, 'lineno', None) else ''
        raise fields.fail(f'{field}.script', f'{name} is not valid Python: {getattr(error, "msg", error)}{where}'
                          ) from None
    return Script(str(path), name, hashlib.sha256(source).hexdigest())


@dataclass(frozen=True)
class _World:
    label: str
    """How the sweep names it (the `world` column): 'default', or the file's name, unique within the sweep."""
    path: str
    """The resolved path, or DEFAULT_WORLD."""
    world: World
    identity: str
    """What the trial key takes from it: 'default', or the file's name and its contents' SHA-256."""


def _world(fields: _Fields, item: Any, field: str) -> _World:
    """The world named by `item`, loaded and checked once however often the spec names it."""
    if item == DEFAULT_WORLD:
        return fields.worlds.setdefault(DEFAULT_WORLD, _World(DEFAULT_WORLD, DEFAULT_WORLD, default_world(),
                                                              DEFAULT_WORLD))
    if not isinstance(item, str):
        raise fields.fail(field, f'expected {DEFAULT_WORLD!r} or a world file, '
                                 f'got {untrusted_yaml.cut(repr(item), 60)}')
    try:
        path = str((fields.path.parent / item).resolve())
        if path not in fields.worlds:
            world = load_world(path)
            digest = hashlib.sha256(read_bounded(path, WORLD_FILE_BYTES)).hexdigest()
            fields.worlds[path] = _World(item, path, world, f'{Path(path).name} sha256:{digest}')
    except ValueError as error:   # WorldError, FileProblem, or a NUL in the name
        raise fields.fail(field, str(error)) from None
    return fields.worlds[path]


def _labelled_worlds(worlds: list[_World]) -> list[_World]:
    """Each world file named by the end of its path that no other world file of the spec shares."""
    files = sorted({world.path for world in worlds if world.path != DEFAULT_WORLD})
    names = unique_names(files)
    return [world if world.path == DEFAULT_WORLD else replace(world, label=names[world.path]) for world in worlds]


def _labelled(controllers: list[Controller | Script]) -> list[Controller | Script]:
    """Each script named by the end of its path that no other script of the spec shares (its file's name, as a
    rule): the table and the picture show it, not the path the spec gave."""
    names = unique_names(sorted({controller.path for controller in controllers if isinstance(controller, Script)}))
    return [replace(controller, name=names[controller.path]) if isinstance(controller, Script) else controller
            for controller in controllers]


def unique_names(paths: list[str]) -> dict[str, str]:
    """Each path's shortest ending (its file's name, then with folders before it) that no other path ends with."""
    parts = {path: Path(path).parts for path in paths}
    names = {}
    for path, mine in parts.items():
        for size in range(1, len(mine) + 1):
            ending = mine[-size:]
            if all(other == path or theirs[-size:] != ending for other, theirs in parts.items()):
                break
        names[path] = '/'.join(ending).lstrip('/') or path
    return names


def _key(controller: Controller | Script, world: _World, robots: int, seed: int, duration: float,
         noise: bool) -> str:
    """What identifies a trial's rows across runs (`--resume`): a hash of everything its rows depend on, the
    script's and world file's contents included, their folders not (a sweep moved elsewhere resumes)."""
    if isinstance(controller, Script):
        who = f'script {Path(controller.path).name} sha256:{controller.digest}'
    else:
        who = json.dumps([controller.behaviour, controller.parameters])
    text = json.dumps([who, world.identity, robots, seed, repr(duration), noise])
    return hashlib.sha256(text.encode()).hexdigest()[:KEY_LENGTH]


def _seeds(fields: _Fields, value: Any) -> list[int]:
    if isinstance(value, dict):
        if set(value) != {'first', 'count'}:
            raise fields.fail('seeds', 'expected a list of seeds or {first: N, count: N}')
        first = fields.integer(value['first'], 'seeds.first', 0, MAX_SEED)
        count = fields.integer(value['count'], 'seeds.count', 1, MAX_TRIALS)
        if first + count - 1 > MAX_SEED:
            raise fields.fail('seeds', f'the last seed, {first + count - 1}, is above {MAX_SEED}')
        return list(range(first, first + count))
    return [fields.integer(seed, f'seeds[{i}]', 0, MAX_SEED) for i, seed in enumerate(fields.items(value, 'seeds'))]
