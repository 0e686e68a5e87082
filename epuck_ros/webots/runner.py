"""`webots_controller`: run an unmodified Webots controller script (Python) against the e-puck simulator.

The script runs as `python SCRIPT.py` would run it (`__name__ == '__main__'`, its folder on the import path,
`sys.argv` = the script and its own arguments) with one difference: `import controller` finds
`epuck_ros/webots/shim/controller`, whose `Robot` talks to the simulator over ROS. Exit code: the script's
(0 when it ends, also on Ctrl-C / SIGTERM through `step() == -1`), 1 with the script's traceback when it
raises, 2 for a bad command line or a robot the simulator does not have.
"""
from __future__ import annotations

import builtins
import re
import sys
import traceback
from pathlib import Path
from types import TracebackType
from typing import NoReturn

import rclpy

from epuck_ros import untrusted_yaml
from epuck_ros.exit_codes import refuse
from epuck_ros.ros.params import HELP_FLAGS, ParameterError, check_arguments, user_arguments
from epuck_ros.webots.link import LinkError
from epuck_ros.ros.spinning import end_process
from epuck_ros.webots.robot import close, configure
from epuck_ros.webots.script_file import FileMissing, FileProblem, read_script

PROGRAM = 'webots_controller'
ROBOT_NAME = re.compile(r'[A-Za-z_][A-Za-z0-9_]*')
SHIM_DIR = Path(__file__).resolve().parent / 'shim'
EXAMPLES_DIR = Path(__file__).resolve().parent / 'examples'
TRACEBACK_LIMIT = 1000
"""The innermost frames a script's traceback shows, as Python's own report does (sys.tracebacklimit's default): a
script that recursed a million frames deep is reported in the time Python takes, not minutes of formatting."""
HELP = f"""usage: {PROGRAM} SCRIPT.py [ARG ...] [--robot NAME] [--ros-args ...]
       {PROGRAM} SCRIPT.py --headless [--world W] [--robots N] [--seed S] [--duration D] [--record BAG]

Run an unmodified Webots controller script (Python: from controller import Robot ...) against the e-puck
simulator over ROS. The script's Robot is one rclpy node: it publishes wheel_cmd and reads /clock,
joint_states and ir_raw; step(32) is exactly one simulator step, and with the simulator in lockstep the run
is the same every time. Start `sim` first, or let `bringup --controller SCRIPT.py` start everything.

--headless runs the script against the simulator's core in this process, without ROS, at full speed: the
same run as `bringup --controller SCRIPT.py --lockstep --real-time-factor 0` (see --headless --help).

options:
  SCRIPT.py [ARG ...]  the controller script and its own arguments (its sys.argv[1:])
  --robot NAME         the robot of a multi-robot world to drive (topics NAME/...); default: the only robot
  --ros-args ...       ROS arguments for the node (remappings, --log-level, -r __ns:=/NS)

exit code: the script's; 0 when Ctrl-C or a vanished simulator ends it (step() returns -1); 1 with the
script's traceback when it raises; 2 for a bad command line or a robot the simulator does not have.

examples (shipped in {EXAMPLES_DIR}):
  sim --ros-args -p lockstep:=true &
  {PROGRAM} {EXAMPLES_DIR / 'avoid_obstacles.py'}
  bringup --controller {EXAMPLES_DIR / 'circle.py'} --duration 20 --record"""


def parse(user: list[str]) -> tuple[str, str, list[str]]:
    """(script, robot, the script's own arguments): `--robot NAME` is ours wherever it is, the rest the script's."""
    robot, rest = '', []
    args = iter(user)
    for arg in args:
        if arg == '--robot' or arg.startswith('--robot='):
            robot = arg.partition('=')[2] if '=' in arg else next(args, '')
            if not ROBOT_NAME.fullmatch(robot):
                fail(f'--robot needs a robot name (letters, digits, _), got {robot!r}')
        else:
            rest.append(arg)
    if not rest:
        fail('no controller script given (usage: webots_controller SCRIPT.py [--robot NAME]; see --help)')
    return rest[0], robot, rest[1:]


def fail(message: str) -> NoReturn:
    refuse(f'{PROGRAM}: {message}')


def check_script(path: Path, name: str) -> None:
    """Exit 2 with one line unless `path` (named `name` by the user) is a script we can read."""
    try:
        read_script(path)
    except FileMissing:
        fail(f'no such controller script: {name}')
    except FileProblem as problem:
        fail(f'controller script {name}: {problem}')


def run_script(path: Path, script_args: list[str]) -> tuple[int, str]:
    """Run the script as __main__: its exit code (1 and its traceback when it raises), and one line saying what
    went wrong ('' when nothing did)."""
    sys.path[:0] = [folder for folder in (str(SHIM_DIR), str(path.parent)) if folder not in sys.path]
    sys.argv = [str(path), *script_args]
    try:
        _run_as_main(path)
    except KeyboardInterrupt:
        return 0, ''
    except SystemExit as end:
        if end.code is None or isinstance(end.code, int):
            return end.code or 0, f'sys.exit({end.code})' if end.code else ''
        print(end.code, file=sys.stderr)
        return 1, f'sys.exit({untrusted_yaml.cut(repr(end.code), 200)})'
    except LinkError as error:
        print(f'{PROGRAM}: {error}', file=sys.stderr)
        return 2, str(error)
    except BaseException as error:  # noqa: BLE001 - whatever the script raises is reported as Python would
        where, line = _from_script(error.__traceback__, str(path))
        traceback.print_exception(type(error), error, where)
        return 1, untrusted_yaml.cut(f'{type(error).__name__}: {error}', 300) + \
            (f' (line {line} of {path.name})' if line else '')
    return 0, ''


def _run_as_main(path: Path) -> None:
    """The script's code in a namespace of its own called __main__, as `python SCRIPT.py` runs it.

    Not runpy.run_path: it puts the script in sys.modules['__main__'] for the run and puts back what it found
    there, and the copies of a script that a headless trial runs at once, one thread per robot, put them back in
    the wrong order, leaving a script as the process's __main__ (multiprocessing's spawned children, Dask's
    workers, then ran that script instead of the program that started them)."""
    code = compile(read_script(path), str(path), 'exec')
    exec(code, {'__name__': '__main__', '__file__': str(path), '__builtins__': builtins,  # noqa: S102 - its purpose
                '__package__': None, '__spec__': None, '__loader__': None, '__cached__': None})


def _from_script(tb: TracebackType | None, path: str) -> tuple[TracebackType | None, int]:
    """The traceback from the script's own frame on (the runner's frames say nothing to its author), at most its
    TRACEBACK_LIMIT innermost frames, and the line of the script's innermost frame (0 if none). One walk along the
    frames: Python's traceback module would locate every frame's columns first, even the ones it leaves out."""
    first, line, frame, depth = None, 0, tb, 0
    while frame is not None:
        if frame.tb_frame.f_code.co_filename == path:
            line = frame.tb_lineno
            first = first or frame
        depth += first is not None
        frame = frame.tb_next
    first = first or tb
    for _ in range(depth - TRACEBACK_LIMIT):
        first = first.tb_next
    return first, line


def main(argv: list[str] | None = None) -> None:
    """The script over ROS (`webots_controller` without --headless: `epuck_ros.webots_controller`)."""
    argv = [PROGRAM, *(sys.argv[1:] if argv is None else argv)]
    if any(arg in HELP_FLAGS for arg in user_arguments(argv)):
        print(HELP)
        raise SystemExit(0)
    try:
        args = check_arguments(argv, [])  # the node has no parameters of its own: `-p typo:=1` is refused
    except ParameterError as error:
        fail(f'{str(error).split(" (known")[0]}: the controller\'s node has no parameters of its own')
    script, robot, script_args = parse(user_arguments(args))
    check_script(Path(script), script)
    path = Path(script).resolve()
    configure(robot, args[1:])
    code = 0
    try:
        code, _ = run_script(path, script_args)
    finally:
        close()
        rclpy.try_shutdown()
    end_process(code)   # not SystemExit: a thread the script left running would keep the process alive
