"""Parameters of every node: one declarative table per executable, checked before any node exists.

Each node lists its parameters as `ParamSpec`s and calls two functions:

- `prepare_arguments(args, specs, usage)` in `main()`, before `rclpy.init`: answers `--help` / `-h` (what the
  executable does, every parameter with default, range and description, an example) and exits 0; refuses an
  unknown `-p NAME:=VALUE` with the closest valid name ("did you mean goal_distance?") and a value of the wrong
  type or out of range, with one line naming the parameter and exit code 2; and writes an integer given for a
  float parameter (`-p real_time_factor:=0`) as a float literal, which rclpy would otherwise refuse
  ("expecting type 'DOUBLE'"). rcl reads the overrides while initialising, so they have to be right before it.
- `declare_parameters(node, specs)` in the node's constructor: declares them with `ParameterDescriptor`s
  (description, range, read_only), and, for values set later through the parameter services, turns an integer
  given for a float parameter into a float before rclpy's type check (a pre-set callback), so
  `ros2 param set /sim real_time_factor 0` works too and the value always reads back as a float.
"""
from __future__ import annotations

import difflib
import re
import sys
import textwrap
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import yaml
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.node import Node
from rclpy.parameter import Parameter

from epuck_ros.exit_codes import refuse

ParamValue = bool | int | float | str

ROS_OWN_PARAMETERS = ('use_sim_time', 'start_type_description_service')
"""Parameters rclpy declares on every node; `qos_overrides.<topic>...` are rclpy's as well."""
PARAM_FLAGS = ('-p', '--param')
PARAMS_FILE_FLAG = '--params-file'
HELP_FLAGS = ('-h', '--help')
_INTEGER = re.compile(r'[-+]?[0-9]+')
# The words rcl's YAML parameter parser reads as booleans (rcl_yaml_param_parser, parse.c).
_TRUE_WORDS = {'true', 'True', 'TRUE', 'yes', 'Yes', 'YES', 'on', 'On', 'ON', 'y', 'Y'}
_FALSE_WORDS = {'false', 'False', 'FALSE', 'no', 'No', 'NO', 'off', 'Off', 'OFF', 'n', 'N'}
_TYPE_NAMES = {bool: 'a boolean (true/false)', int: 'an integer', float: 'a number', str: 'a string'}


class ParameterError(ValueError):
    """A parameter override the node refuses: the message names the parameter."""


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: its type is the default's type (bool, int, float or str)."""

    name: str
    default: ParamValue
    description: str
    range: tuple[float, float] | None = None
    """Inclusive (low, high) for int and float parameters; None = any value of the type."""
    read_only: bool = False

    @property
    def type(self) -> type:
        return type(self.default)

    def descriptor(self) -> ParameterDescriptor:
        descriptor = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if self.range is not None and self.type is int:
            low, high = self.range
            descriptor.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
        elif self.range is not None and self.type is float:
            low, high = self.range
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
        return descriptor

    def check(self, value: Any) -> ParamValue:
        """The value as this parameter's type (an int for a float becomes a float); ParameterError if it cannot be."""
        if self.type is float and isinstance(value, int) and not isinstance(value, bool):
            try:
                value = float(value)
            except OverflowError:
                raise ParameterError(f'{self.name}: {value} is too large') from None
        if type(value) is not self.type:
            raise ParameterError(
                f'{self.name}: expected {_TYPE_NAMES[self.type]}, got {_show(value)} ({type(value).__name__})')
        if self.range is not None:
            low, high = self.range
            if not low <= value <= high:  # NaN fails this too
                raise ParameterError(f'{self.name}: {value} is out of range [{low:g}, {high:g}]')
        return value


@dataclass(frozen=True)
class Usage:
    """What `--help` says about an executable besides its parameters."""

    program: str
    summary: str
    """What the executable does, one or a few sentences."""
    example: str
    """A complete command line."""
    options: str = ''
    """Help for command-line options of the executable itself (before `--ros-args`), if it has any."""


def declare_parameters(node: Node, specs: Iterable[ParamSpec]) -> dict[str, ParamValue]:
    """Declare every spec on `node` with its descriptor; returns name -> value (defaults or overrides)."""
    specs = list(specs)
    by_name = {spec.name: spec for spec in specs}

    def integers_as_floats(params: list[Parameter]) -> list[Parameter]:
        return [Parameter(p.name, Parameter.Type.DOUBLE, float(p.value))
                if p.type_ == Parameter.Type.INTEGER and p.name in by_name and by_name[p.name].type is float
                else p for p in params]

    node.add_pre_set_parameters_callback(integers_as_floats)
    declared = node.declare_parameters('', [(spec.name, spec.default, spec.descriptor()) for spec in specs])
    return {param.name: param.value for param in declared}


def prepare_arguments(args: Sequence[str] | None, specs: Iterable[ParamSpec], usage: Usage,
                      own_options: bool = False) -> list[str]:
    """The command line for `rclpy.init`, after `--help` (exits 0) and checking every parameter (exits 2).

    `args` defaults to `sys.argv`. Parameter overrides are checked whether they come from `-p` or a
    `--params-file`; a node-qualified override (`-p other_node:name:=value`) is left to that node. Unless the
    executable has `own_options` (it parses the arguments outside `--ros-args` itself), any such argument is
    refused: `sim -p seed:=3` without `--ros-args` would otherwise be silently ignored by rclpy.
    """
    args = list(sys.argv if args is None else args)
    specs = list(specs)
    user = user_arguments(args)
    if any(arg in HELP_FLAGS for arg in user):
        print(help_text(specs, usage))
        raise SystemExit(0)
    if user and not own_options:
        _fail(usage.program, f'unexpected argument {user[0]!r}: parameters go after --ros-args '
                             f'(e.g. {usage.program} --ros-args -p NAME:=VALUE); see {usage.program} --help')
    try:
        return check_arguments(args, specs)
    except ParameterError as error:
        _fail(usage.program, str(error))


def check_arguments(args: Sequence[str], specs: Iterable[ParamSpec]) -> list[str]:
    """`args` with integer values of float parameters written as floats; ParameterError for a refused override."""
    by_name = {spec.name: spec for spec in specs}
    result = list(args)
    for index in _ros_argument_positions(result):
        flag = result[index]
        if flag in PARAM_FLAGS:
            if index + 1 >= len(result):
                raise ParameterError(f'{flag} needs NAME:=VALUE after it')
            result[index + 1] = _check_assignment(result[index + 1], by_name)
        elif flag == PARAMS_FILE_FLAG and index + 1 < len(result):
            _check_params_file(result[index + 1], by_name)
    return result


def command_line_value(args: Sequence[str], name: str) -> Any:
    """The value the last `-p name:=VALUE` inside `--ros-args` gives `name` (as rcl reads it), or None: for the
    few settings a process must know before rclpy starts (a parameter file is not looked at)."""
    args, value = list(args), None
    for index in _ros_argument_positions(args):
        if args[index] in PARAM_FLAGS and index + 1 < len(args):
            key, sep, text = args[index + 1].partition(':=')
            if sep and key.rpartition(':')[2] == name:
                value = _parse_value(text)
    return value


def user_arguments(args: Sequence[str]) -> list[str]:
    """The arguments outside `--ros-args ... [--]` (argv[0] excluded): those the executable itself reads."""
    user, inside = [], False
    for arg in list(args)[1:]:
        if arg == '--ros-args':
            inside = True
        elif arg == '--' and inside:
            inside = False
        elif not inside:
            user.append(arg)
    return user


def help_text(specs: Iterable[ParamSpec], usage: Usage) -> str:
    """What `--help` prints: the summary, options, a parameter table and an example."""
    rows = [(spec.name, _show(spec.default), _range_text(spec), spec.description + (' (read-only)' if spec.read_only
                                                                                    else '')) for spec in specs]
    widths = [max([len(header)] + [len(row[i]) for row in rows])
              for i, header in enumerate(('name', 'default', 'range'))]
    lines = [f'usage: {usage.program} [-h] [--ros-args -p NAME:=VALUE ...]', '', textwrap.fill(usage.summary, 100), '']
    if usage.options:
        lines += ['options:', usage.options.rstrip(), '']
    lines.append('parameters (--ros-args -p NAME:=VALUE; integers are accepted for numbers):')
    header = ('name', 'default', 'range', 'description')
    for row in [header, *rows]:
        lines.append('  ' + '  '.join(cell.ljust(width) for cell, width in zip(row, widths)) + '  ' + row[3])
    lines += ['', 'also: use_sim_time (rclpy), remappings (-r), --log-level', '', 'example:', f'  {usage.example}']
    return '\n'.join(lines)


def _ros_argument_positions(args: list[str]) -> list[int]:
    """The index of each argument inside a `--ros-args ... [--]` region."""
    positions, inside = [], False
    for index, arg in enumerate(args[1:], start=1):
        if arg == '--ros-args':
            inside = True
        elif arg == '--' and inside:
            inside = False
        elif inside:
            positions.append(index)
    return positions


def _check_assignment(assignment: str, by_name: dict[str, ParamSpec]) -> str:
    name, sep, text = assignment.partition(':=')
    if not sep or not name:
        raise ParameterError(f'-p {assignment}: expected NAME:=VALUE')
    node, colon, short = name.rpartition(':')
    if colon and node:
        return assignment  # meant for the node called `node`, which checks it itself
    spec = _spec_for(short, by_name)
    if spec is None:
        return assignment
    if text == '':
        raise ParameterError(f'{short}: empty value (write -p {short}:=VALUE)')
    value = _parse_value(text)
    if spec.type is str:  # `-p world:=3` means the text '3', not an integer
        return assignment if isinstance(value, str) else f'{name}:={_quoted(text)}'
    value = spec.check(value)
    return f'{name}:={value!r}' if spec.type is float else assignment


def _check_params_file(path: str, by_name: dict[str, ParamSpec]) -> None:
    try:
        document = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError, UnicodeDecodeError) as error:
        raise ParameterError(f'--params-file {path}: cannot read it ({error.__class__.__name__})') from None
    if not isinstance(document, dict):
        raise ParameterError(f'--params-file {path}: expected a mapping of node names to ros__parameters')
    for section in document.values():
        params = section.get('ros__parameters') if isinstance(section, dict) else None
        for name, value in _flatten(params if isinstance(params, dict) else {}):
            spec = _spec_for(name, by_name)
            if spec is not None and not (spec.type is float and isinstance(value, int)):
                spec.check(value)  # an integer for a float here is still rclpy's type error: say it
            elif spec is not None:
                raise ParameterError(f'{name}: write {value}.0 in {path} (rclpy takes only floats for it)')


def _spec_for(name: str, by_name: dict[str, ParamSpec]) -> ParamSpec | None:
    """The spec of `name`; None for rclpy's own parameters; ParameterError naming the closest for a typo."""
    if name in by_name:
        return by_name[name]
    if name in ROS_OWN_PARAMETERS or name.startswith('qos_overrides.'):
        return None
    close = difflib.get_close_matches(name, list(by_name), n=1, cutoff=0.6)
    hint = f' (did you mean {close[0]}?)' if close else f' (known: {", ".join(by_name)})'
    raise ParameterError(f'unknown parameter {name!r}{hint}')


def _parse_value(text: str) -> Any:
    """The value rcl reads from `-p name:=TEXT`: a bool word, an integer, a number, a list or a string."""
    if len(text) >= 2 and text[0] == text[-1] and text[0] in '\'"':
        return text[1:-1]
    if text in _TRUE_WORDS or text in _FALSE_WORDS:
        return text in _TRUE_WORDS
    if _INTEGER.fullmatch(text):
        return int(text)
    if text.startswith('['):
        return _quoted(text)  # a list: no parameter here takes one, so it is a type error below
    try:
        return float(text)
    except ValueError:
        return text


def _flatten(params: dict[str, Any], prefix: str = '') -> list[tuple[str, Any]]:
    items = []
    for key, value in params.items():
        name = f'{prefix}{key}'
        items += _flatten(value, name + '.') if isinstance(value, dict) else [(name, value)]
    return items


def _quoted(text: str) -> str:
    return "'" + text.replace("'", "''") + "'"


def _show(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, str):
        return repr(value) if value == '' or not value.isprintable() else value
    return repr(value) if isinstance(value, float) else str(value)


def _range_text(spec: ParamSpec) -> str:
    if spec.range is None:
        return {bool: 'true/false', str: 'text'}.get(spec.type, 'any')
    low, high = spec.range
    return f'{int(low)} .. {int(high)}' if spec.type is int else f'{low:g} .. {high:g}'


def _fail(program: str, message: str) -> NoReturn:
    refuse(f'{program}: {message}')
