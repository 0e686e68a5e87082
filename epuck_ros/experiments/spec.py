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
```
"""
from __future__ import annotations

import difflib
import itertools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from epuck_ros import untrusted_yaml
from epuck_ros.behaviours import BEHAVIOURS, ConfigError
from epuck_ros.behaviours.base import describe
from epuck_ros.experiments.trial import DEFAULT_TIME_LIMIT, DEFAULT_WORLD, Controller, Script, Trial
from epuck_ros.simulation import MAX_SEED
from epuck_ros.world import World, WorldError, default_world, load_world, place_robots

MAX_TRIALS = 100_000
"""Trials in one spec at most (a typo such as `count: 1e9` would otherwise queue a billion)."""
MAX_DURATION = 3600.0
"""Simulated seconds per trial at most."""
MAX_ROBOTS = 10_000
MAX_FILE_BYTES = 1 << 20
MAX_TIME_LIMIT = 86_400.0
KEYS = ('controllers', 'worlds', 'robots', 'seeds', 'duration', 'noise', 'time_limit')


class SpecError(ValueError):
    """The spec cannot be run; the message names the file and field."""


@dataclass(frozen=True)
class Spec:
    path: Path
    trials: tuple[Trial, ...]


def load_spec(path: Path) -> Spec:
    """The spec at `path`, every field checked (SpecError), every trial made."""
    try:
        text = path.read_text(encoding='utf-8') if path.stat().st_size <= MAX_FILE_BYTES else None
    except (OSError, UnicodeDecodeError) as error:
        raise SpecError(f'{path}: cannot read the spec: {getattr(error, "strerror", None) or error}') from None
    if text is None:
        raise SpecError(f'{path}: larger than {MAX_FILE_BYTES} bytes')
    try:
        data = untrusted_yaml.load(text, 8)
    except untrusted_yaml.UntrustedYamlError as error:
        raise SpecError(f'{path}: {error}') from None
    return Spec(path, tuple(_trials(_Fields(path), data)))


class _Fields:
    """Typed access to the spec's fields; each failure a SpecError naming the file and field."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, field: str, problem: str) -> SpecError:
        return SpecError(f'{self.path}: {field}: {problem}')

    def items(self, value: Any, field: str) -> list[Any]:
        if not isinstance(value, list) or not value:
            raise self.fail(field, f'expected a non-empty list, got {untrusted_yaml.cut(repr(value), 60)}')
        return value

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
    controllers = [_controller(fields, item, f'controllers[{i}]')
                   for i, item in enumerate(fields.items(data['controllers'], 'controllers'))]
    # each world file read once, however often the spec names it (a 100-entry list of one file was read 100 times)
    loaded: dict[str, World] = {DEFAULT_WORLD: default_world()}
    worlds = [_world(fields, item, f'worlds[{i}]', loaded)
              for i, item in enumerate(fields.items(data.get('worlds', [DEFAULT_WORLD]), 'worlds'))]
    robots = [fields.integer(item, f'robots[{i}]', 0, MAX_ROBOTS)
              for i, item in enumerate(fields.items(data.get('robots', [1]), 'robots'))]
    seeds = _seeds(fields, data['seeds'])
    duration = data['duration']
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not 0 < duration <= MAX_DURATION:
        raise fields.fail('duration', f'expected simulated seconds above 0 and at most {MAX_DURATION:g}, '
                                      f'got {untrusted_yaml.cut(repr(duration), 60)}')
    noise = data.get('noise', True)
    if not isinstance(noise, bool):
        raise fields.fail('noise', f'expected true or false, got {untrusted_yaml.cut(repr(noise), 60)}')
    limit = data.get('time_limit', DEFAULT_TIME_LIMIT)
    if isinstance(limit, bool) or not isinstance(limit, (int, float)) or not 0 < limit <= MAX_TIME_LIMIT:
        raise fields.fail('time_limit', f'expected wall seconds above 0 and at most {MAX_TIME_LIMIT:g}, '
                                        f'got {untrusted_yaml.cut(repr(limit), 60)}')
    count = len(controllers) * len(worlds) * len(robots) * len(seeds)
    if count > MAX_TRIALS:
        raise fields.fail('<top level>', f'{count} trials, more than {MAX_TRIALS} in one spec: split it')
    for (label, world), robot_count in itertools.product(worlds, robots):   # placement fails before any trial
        if robot_count > 1:
            try:
                place_robots(loaded[world], robot_count, 0)
            except WorldError as error:
                raise fields.fail('robots', f'{robot_count} in {label}: {error}') from None
    return [Trial(controller, world, robot_count if robot_count > 1 else 0, seed, float(duration), noise, index,
                  label, float(limit))
            for index, (controller, (label, world), robot_count, seed)
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
    controller = Controller(name, tuple(sorted(parameters.items())))
    try:
        controller.make()
    except (ConfigError, TypeError, ValueError) as error:
        raise fields.fail(f'{field}.parameters', str(error)) from None
    return controller


def _script(fields: _Fields, item: dict, field: str) -> Script:
    """A Webots-style script: it must exist and compile (a syntax error would otherwise fail every trial)."""
    if set(item) != {'script'}:
        unknown = sorted(str(key) for key in item if key != 'script')
        raise fields.fail(f'{field}.{unknown[0]}', 'unknown key (a script controller is {script: PATH})')
    name = item['script']
    if not isinstance(name, str) or not name:
        raise fields.fail(f'{field}.script', f'expected the path of a Python script, got '
                                             f'{untrusted_yaml.cut(repr(name), 60)}')
    path = (fields.path.parent / name).resolve()
    try:
        source = path.read_bytes() if path.stat().st_size <= MAX_FILE_BYTES else None
    except OSError as error:
        raise fields.fail(f'{field}.script', f'cannot read {name}: {error.strerror}') from None
    if source is None:
        raise fields.fail(f'{field}.script', f'{name} is larger than {MAX_FILE_BYTES} bytes')
    try:
        compile(source, str(path), 'exec')
    except (SyntaxError, ValueError) as error:
        where = f' (line {error.lineno})' if getattr(error, 'lineno', None) else ''
        raise fields.fail(f'{field}.script', f'{name} is not valid Python: {getattr(error, "msg", error)}{where}'
                          ) from None
    return Script(str(path), name)


def _world(fields: _Fields, item: Any, field: str, loaded: dict[str, World]) -> tuple[str, str]:
    """(the spec's label, the path or DEFAULT_WORLD), the world loaded into `loaded` to check it, unless it is
    there already."""
    if item == DEFAULT_WORLD:
        return DEFAULT_WORLD, DEFAULT_WORLD
    if not isinstance(item, str):
        raise fields.fail(field, f'expected {DEFAULT_WORLD!r} or a world file, '
                                 f'got {untrusted_yaml.cut(repr(item), 60)}')
    path = (fields.path.parent / item).resolve()
    if str(path) not in loaded:
        try:
            loaded[str(path)] = load_world(path)
        except WorldError as error:
            raise fields.fail(field, str(error)) from None
    return item, str(path)


def _seeds(fields: _Fields, value: Any) -> list[int]:
    if isinstance(value, dict):
        if set(value) != {'first', 'count'}:
            raise fields.fail('seeds', 'expected a list of seeds or {first: N, count: N}')
        first = fields.integer(value['first'], 'seeds.first', 0, MAX_SEED)
        count = fields.integer(value['count'], 'seeds.count', 1, min(MAX_TRIALS, MAX_SEED - first + 1))
        return list(range(first, first + count))
    return [fields.integer(seed, f'seeds[{i}]', 0, MAX_SEED) for i, seed in enumerate(fields.items(value, 'seeds'))]
