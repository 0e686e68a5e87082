"""`bringup`'s command line: options, and every `-p` checked against the parameter table of the node it is for,
before anything starts (a typo gets the closest valid name and exit code 2, never a silently ignored value).
"""
from __future__ import annotations

import argparse
import ast
import math
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

from rclpy.exceptions import InvalidNamespaceException
from rclpy.validate_namespace import validate_namespace

from epuck_ros.behaviours import BEHAVIOURS
from epuck_ros.bringup import tables
from epuck_ros.exit_codes import refuse
from epuck_ros.foxglove.address import DEFAULT_HOST as FOXGLOVE_HOST
from epuck_ros.foxglove.address import DEFAULT_PORT as FOXGLOVE_PORT
from epuck_ros.foxglove.address import address_error
from epuck_ros.ros.params import ParameterError, ParamSpec, check_arguments
from epuck_ros.world import WorldError, load_world, placed_names

WEBOTS_MODULE = 'controller'
"""A script importing this module is a Webots controller: it runs through `webots_controller`."""


@dataclass
class Plan:
    """What `bringup` starts, decided from the command line alone."""

    controller: str
    """The behaviour's name, or the controller script's file name."""
    controller_kind: str
    """'behaviour', 'webots' (a Webots-style script) or 'rclpy' (a student's own node)."""
    controller_command: list[str]
    """Executable (or script) and its own arguments, without --ros-args."""
    robots_to_drive: str | tuple[str, ...]
    """'all', 'any', or the names that must have a controller connected before the run starts."""
    script_robots: tuple[str, ...] = ()
    """A Webots script on several robots: one webots_controller per robot named here, as Webots runs one
    controller per robot (and as a headless trial of the script runs one copy per robot)."""
    sim_params: list[str] = field(default_factory=list)
    controller_params: list[str] = field(default_factory=list)
    view_params: list[str] = field(default_factory=list)
    view_url: str = ''
    record_dir: Path | None = None
    foxglove_port: int | None = None
    """The Foxglove bridge's port on FOXGLOVE_HOST (0: any free one, which its own line says); None: no bridge."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:
        """One line and exit code 2 (not argparse's usage block): the mistake is what the user must see."""
        refuse(f'{self.prog}: error: {message} (see {self.prog} --help)')


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog='bringup', formatter_class=argparse.RawDescriptionHelpFormatter,
        description='Run the e-puck simulator with a course behaviour or your own controller, optionally the MCAP '
                    'recorder and the browser view, each as its own process; stop them all at the end.\n'
                    'The simulator starts paused and resumes once every controller is connected, so runs start at '
                    't = 0; by default it runs in lockstep (it waits for the controllers every step), so a run is '
                    'the same however busy the machine is.',
        epilog='examples:\n'
               '  bringup avoid --duration 60 --record                  # 60 simulated s, recorded to bags/\n'
               '  bringup rectangle --duration 30 -p turn_mode:=timed --real-time-factor 0\n'
               '  bringup avoid --robots 20 --duration 60 --record      # 20 robots, one avoid process\n'
               '  bringup --controller my_controller.py --duration 20   # a Webots-style or rclpy script\n'
               '  bringup avoid --view                                  # and watch it on http://127.0.0.1:8765/\n'
               '  bringup avoid --foxglove                              # in Foxglove: ws://127.0.0.1:8765')
    _add_what_runs(parser)
    _add_how_it_runs(parser)
    _add_what_else_starts(parser)
    return parser


def _add_what_runs(parser: argparse.ArgumentParser) -> None:
    """The controller and the robots it drives."""
    parser.add_argument('behaviour', nargs='?', choices=tuple(BEHAVIOURS),
                        help='the course behaviour to run (default: avoid, unless --controller is given)')
    parser.add_argument('--controller', metavar='SCRIPT.py',
                        help='run this controller script instead of a behaviour: a Webots controller (it imports '
                             '`controller`) goes through webots_controller, any other script runs as an rclpy node '
                             'with use_sim_time')
    parser.add_argument('--robot', metavar='NAME',
                        help='the robot a --controller script drives (several robots); without it a Webots script '
                             'runs once per robot, as in Webots')
    parser.add_argument('--robots', type=int, metavar='N',
                        help='simulate N robots placed clear of everything (seeded); the behaviour drives them all')


def _add_how_it_runs(parser: argparse.ArgumentParser) -> None:
    """The run's length, world, randomness and pace, and the nodes' parameters."""
    parser.add_argument('--duration', type=float, default=0.0,
                        help='simulated seconds after which the run ends by itself, on the first 32 ms step at or '
                             'after it (10 ends at 10.016 s; default: until Ctrl-C)')
    parser.add_argument('--world', default='', help='world YAML file (default: the built-in 1 m x 1 m arena)')
    parser.add_argument('--seed', type=int, default=0, help='seed of every random draw (default 0)')
    parser.add_argument('--real-time-factor', type=float, default=1.0,
                        help='simulated seconds per wall second; 0 = as fast as possible (default 1)')
    parser.add_argument('--no-noise', action='store_true', help='turn the sensor noise off')
    parser.add_argument('--lockstep', action=argparse.BooleanOptionalAction, default=True,
                        help='the simulator waits for every controller\'s command after each step, so a run does not '
                             'depend on the machine\'s load (default); --no-lockstep keeps the simulator\'s own '
                             'pace, like a real robot: a slow controller reacts late')
    parser.add_argument('-p', '--param', action='append', default=[], metavar='[NODE.]NAME:=VALUE',
                        help='a parameter for the node that declares it (sim parameters go to sim, the rest to the '
                             'behaviour; view.NAME to the view); repeatable')


def _add_what_else_starts(parser: argparse.ArgumentParser) -> None:
    """The recorder, the view, the Foxglove bridge, and the run's namespace and logs."""
    parser.add_argument('--record', nargs='?', const='', default=None, metavar='DIR',
                        help='record all topics to an MCAP bag (default folder: bags/rosbag2_<date>); the camera, '
                             'ground, light and IMU topics are in it while the controller (or the view) reads them: '
                             'add -p senses:=camera,ground,light,imu to render and record them anyway')
    parser.add_argument('--record-compression', choices=('none', 'zstd', 'lz4'), default='none',
                        help='chunk compression of the recording (default none, as rosbag2)')
    parser.add_argument('--view', action='store_true', help='also start the browser view and print its URL')
    parser.add_argument('--foxglove', nargs='?', type=int, const=FOXGLOVE_PORT, default=None, metavar='PORT',
                        help=f'also serve the run to Foxglove on ws://{FOXGLOVE_HOST}:PORT (default {FOXGLOVE_PORT}; '
                             '0 = any free port): every topic, the simulation\'s time as the server\'s; a topic is '
                             'read only while a Foxglove panel shows it, so the camera is rendered only while an image '
                             'panel shows it (see foxglove --help)')
    parser.add_argument('--namespace', default='', help='ROS namespace of the simulation (e.g. class1)')
    parser.add_argument('--verbose', action='store_true',
                        help='also show the behaviour\'s state changes (cruising, turning, ...: its DEBUG lines)')


def parse_args(argv: list[str]) -> tuple[argparse.Namespace, Plan]:
    """The options and the plan; exits 2 with one line on any mistake."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args, make_plan(args)
    except (ParameterError, WorldError, ValueError) as error:
        parser.error(str(error).splitlines()[0] if str(error) else repr(error))


def make_plan(args: argparse.Namespace) -> Plan:
    if args.behaviour and args.controller:
        raise ValueError(f'give a behaviour ({args.behaviour}) or --controller, not both')
    if not math.isfinite(args.duration) or args.duration < 0:
        raise ValueError('--duration must be a non-negative number of simulated seconds')
    if not math.isfinite(args.real_time_factor) or args.real_time_factor < 0:
        raise ValueError('--real-time-factor must be >= 0')
    if args.robots is not None and args.robots < 1:
        raise ValueError('--robots must be at least 1')
    if args.namespace:
        try:
            validate_namespace('/' + args.namespace.strip('/'))
        except InvalidNamespaceException as error:
            raise ValueError(f'--namespace {args.namespace!r}: {str(error).splitlines()[0].rstrip(": ")}') from None
    if args.controller and not Path(args.controller).is_file():
        raise ValueError(f'--controller: no such file: {args.controller}')
    names = _robot_names(args)
    if args.robot and not args.controller:
        raise ValueError('--robot picks the robot of a --controller script; a behaviour drives every robot')
    if args.robot and names and args.robot not in names:
        raise ValueError(f'--robot {args.robot}: no such robot (robots: {", ".join(names)})')
    several = len(names) > 1 or (args.robots or 1) > 1
    plan = _controller_plan(args, several)
    if several and plan.controller_kind == 'webots' and not args.robot:
        plan.script_robots = placed_names(args.robots) if args.robots else names
    if args.controller and args.robot:
        plan.robots_to_drive = (args.robot,)
    sim_specs = tables.sim_parameters()
    controller_specs = tables.controller_parameters(plan.controller_kind, plan.controller)
    view_specs = tables.view_parameters() if args.view else None
    routed: dict[str, list[str]] = {'sim': [], 'controller': [], 'view': []}
    for assignment in args.param:
        target, assignment = _target(assignment, plan, sim_specs, controller_specs, view_specs)
        routed[target].append(assignment)
    plan.sim_params = _checked(_sim_options(args) + routed['sim'], sim_specs)
    plan.controller_params = (routed['controller'] if controller_specs is None
                              else _checked(routed['controller'], controller_specs))
    if args.view:
        plan.view_params = _checked(routed['view'], view_specs)
        plan.view_url = tables.view_url(plan.view_params)
    if args.foxglove is not None:
        plan.foxglove_port = _foxglove_port(args.foxglove, plan.view_url)
    if args.record is not None:
        plan.record_dir = Path(args.record) if args.record else tables.default_bag_folder()
        if plan.record_dir.exists():
            raise ValueError(f'--record {plan.record_dir}: already exists (pick a new folder)')
    return plan


def _foxglove_port(port: int, view_url: str) -> int:
    """The bridge's port, checked before anything starts: taken, or the view's too, is a refusal."""
    problem = address_error(FOXGLOVE_HOST, port)
    if problem is not None:
        raise ValueError(f'--foxglove {port}: cannot serve on {FOXGLOVE_HOST}:{port}: {problem}')
    if port and view_url.endswith(f':{port}/'):
        raise ValueError(f'--foxglove {port}: the view serves on port {port} too: give --foxglove another port '
                         f'(--foxglove {port + 1}) or the view another (-p view.port:=8080)')
    return port


def _robot_names(args: argparse.Namespace) -> tuple[str, ...]:
    """The robots the world file declares (checked now, so a bad file stops everything before it starts)."""
    if not args.world:
        return ()
    if not Path(args.world).is_file():
        raise ValueError(f'--world: no such file: {args.world}')
    world = load_world(args.world)
    return () if args.robots else world.names


def _controller_plan(args: argparse.Namespace, several: bool) -> Plan:
    if not args.controller:
        behaviour = args.behaviour or 'avoid'
        verbose = ['--ros-args', '--log-level', f'{behaviour}:=debug', '--'] if args.verbose else []
        return Plan(behaviour, 'behaviour', [behaviour, *(['--robots', 'all'] if several else []), *verbose],
                    'all')
    script = Path(args.controller)
    if _is_webots(script):
        command = ['webots_controller', str(script.resolve()), *(['--robot', args.robot] if args.robot else [])]
        return Plan(script.name, 'webots', command, 'all' if several and not args.robot else 'any')
    return Plan(script.name, 'rclpy', [sys.executable, str(script.resolve())], 'any')


def _is_webots(script: Path) -> bool:
    """Whether the script is a Webots controller (it imports `controller`); ValueError if it is not Python."""
    try:
        tree = ast.parse(script.read_bytes(), filename=str(script))
    except (SyntaxError, ValueError, OSError) as error:
        raise ValueError(f'--controller {script}: not a readable Python script ({error})') from None
    return imports_module(tree, WEBOTS_MODULE)


def imports_module(tree: ast.AST, module: str) -> bool:
    """Whether the script imports `module` anywhere (`import controller`, `from controller import Robot`)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import) and any(alias.name.split('.')[0] == module for alias in node.names):
            return True
        if isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or '').split('.')[0] == module:
            return True
    return False


def _sim_options(args: argparse.Namespace) -> list[str]:
    """The simulator's parameters from bringup's own options. It starts paused; `bringup` resumes it once every
    controller is connected, so all start at t = 0, and it pauses itself exactly at `pause_at` = the duration. It
    steps at once when resumed (discovery_window 0): `bringup` has looked for another simulator on the domain for
    at least as long by then (with a window of its own the first step came well after the resume, as long as a
    whole short run at full speed: benchmarks/bench_bringup.py times runs from the resume and from the first step)."""
    options = ['paused:=true', f'pause_at:={float(args.duration)}', 'discovery_window:=0.0', f'seed:={args.seed}',
               f'real_time_factor:={float(args.real_time_factor)}', f'lockstep:={str(args.lockstep).lower()}']
    if args.world:
        options.append(f'world:={Path(args.world).resolve()}')
    if args.no_noise:
        options.append('noise:=false')
    if args.robots:
        options.append(f'robots:={args.robots}')
    return options


def _target(assignment: str, plan: Plan, sim: list[ParamSpec], controller: list[ParamSpec] | None,
            view: list[ParamSpec] | None) -> tuple[str, str]:
    """Which node an assignment is for, and the assignment without the node prefix."""
    name, sep, value = assignment.partition(':=')
    if not sep or not name:
        raise ParameterError(f'-p {assignment}: expected NAME:=VALUE')
    if not value:
        raise ParameterError(f'-p {assignment}: empty value (write -p {name}:=VALUE)')
    node, dot, short = name.partition('.')
    if dot and node in ('sim', 'view', 'controller', plan.controller, Path(plan.controller).stem):
        target = {'sim': 'sim', 'view': 'view'}.get(node, 'controller')
        if target == 'view' and view is None:
            raise ParameterError(f'-p {assignment}: the view runs only with --view')
        return target, f'{short}:={value}'
    if dot and node not in _names(sim) + _names(controller) + _names(view):
        raise ParameterError(f'-p {assignment}: unknown node {node!r} '
                             f'(use sim, {plan.controller}{", view" if view is not None else ""})')
    if name in _names(sim):
        return 'sim', assignment
    if controller is None or name in _names(controller):
        return 'controller', assignment
    if view is not None and name in _names(view):
        return 'view', assignment
    # Unknown everywhere: let the tables' own check name the closest valid name.
    check_arguments(['bringup', '--ros-args', '-p', assignment], sim + (controller or []) + (view or []))
    raise ParameterError(f'unknown parameter {name!r}')


def _names(specs: list[ParamSpec] | None) -> list[str]:
    return [spec.name for spec in specs or []]


def _checked(assignments: list[str], specs: list[ParamSpec]) -> list[str]:
    """The assignments as the node will read them (an integer for a float written as a float); ParameterError if
    the node would refuse one."""
    args = ['bringup', '--ros-args', *[arg for a in assignments for arg in ('-p', a)]]
    return check_arguments(args, specs)[3::2]


def ros_domain() -> str:
    """The ROS domain this run uses, as a line for the user."""
    domain = os.environ.get('ROS_DOMAIN_ID', '')
    return (f'ROS_DOMAIN_ID={domain}' if domain else
            'ROS_DOMAIN_ID unset: domain 0 (export ROS_DOMAIN_ID=N to keep runs apart)')
