"""Child processes of `bringup`: started so that they end with it however it ends, stopped in order.

Two guards, because `bringup` itself may die by SIGKILL, which it cannot handle:

- on Linux each child asks the kernel for SIGTERM when its parent dies (`prctl(PR_SET_PDEATHSIG)`),
  which ROS nodes treat like Ctrl-C (a recorder still closes its bag);
- a small watchdog process (`python -m epuck_ros.bringup.watchdog`) holds the read end of a pipe from
  `bringup` and learns every child's pid; when the pipe closes without a "done" line, `bringup` is
  gone: it sends SIGTERM to the children still alive, then SIGKILL to any that ignored it.
"""
from __future__ import annotations

import collections
import ctypes
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

STOP_SIGNALS = ((signal.SIGINT, 10.0), (signal.SIGTERM, 5.0))
"""How `bringup` asks a child to end, as `ros2 launch` does: Ctrl-C (SIGINT) first, which an rclpy node's usual
`except KeyboardInterrupt` handles (SIGTERM ends its spin with ExternalShutdownException: a user's node written
with only that `except` ended every run with a traceback and exit 1); SIGTERM if it is still running after the
first grace (wall seconds), SIGKILL after the second."""
STOP_TIMEOUT = sum(grace for _, grace in STOP_SIGNALS)
"""Wall seconds a child has to end once asked before it is killed."""
MAX_LINE = 64 * 1024
"""Bytes of one line of a child's output forwarded at most; the rest of a longer line is dropped."""
READ_CHUNK = 64 * 1024
_LINE_END = re.compile(rb'\r\n|[\r\n]')
ERROR_LINES = 5
"""Lines of a child's output kept to explain its failure."""
_OUTPUT = threading.Lock()
"""Held while one line goes out: the children's forwarding threads and bringup's own messages share the terminal."""
PR_SET_PDEATHSIG = 1  # <linux/prctl.h>
CLEAN_EXIT_CODES = (0, -signal.SIGINT, 128 + signal.SIGINT, -signal.SIGTERM, 128 + signal.SIGTERM)


def say(line: str, stream: TextIO | None = None) -> bool:
    """Write `line` and its newline in one piece, never inside another's line (print() writes the two apart, and a
    child's line once ran into bringup's next: `...(t=0.000 s)[bringup] running avoid`); default stream: stdout.
    False when the stream is gone (a closed pipe): there is no one left to tell."""
    stream = sys.stdout if stream is None else stream
    with _OUTPUT:
        try:
            stream.write(line + '\n')
            stream.flush()
        except (OSError, ValueError):   # BrokenPipeError, or a closed stream
            return False
    return True


def _prctl() -> Callable[..., int] | None:
    """The prctl of libc, looked up before any fork (nothing may be loaded between fork and exec)."""
    if not sys.platform.startswith('linux'):
        return None
    try:
        return ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None


_PRCTL = _prctl()


def _die_with(parent: int) -> Callable[[], None]:
    """A preexec_fn: SIGTERM this child when `parent` dies; if it already has, end now."""
    def preexec() -> None:
        if _PRCTL is not None:
            _PRCTL(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
        if os.getppid() != parent:  # the parent died before prctl took effect
            os.kill(os.getpid(), signal.SIGTERM)
    return preexec


def process_start_time(pid: int) -> str | None:
    """The kernel's start time of `pid` (field 22 of /proc/PID/stat): with the pid, it names one process."""
    try:
        stat = Path(f'/proc/{pid}/stat').read_text()
    except OSError:
        return None
    fields = stat[stat.rindex(')') + 2:].split()
    return None if fields[0] == 'Z' else fields[19]


def executable(name: str) -> str:
    """The package executable next to this interpreter (venv bin/, colcon lib/epuck_ros/), else on PATH."""
    for folder in (Path(sys.argv[0]).resolve().parent, Path(sys.executable).parent):
        if (folder / name).is_file():
            return str(folder / name)
    found = shutil.which(name)
    if not found:
        raise FileNotFoundError(f'cannot find the executable {name!r} next to {sys.argv[0]} or on PATH')
    return found


@dataclass
class Child:
    """A started process, its role in the run, and the tail of its output for error reports."""

    role: str
    name: str
    process: subprocess.Popen
    tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=ERROR_LINES))
    output_done: threading.Event = field(default_factory=threading.Event)
    echo: bool = True
    """Whether its lines still go to bringup's output (not once that is gone)."""

    def forward_output(self) -> None:
        r"""Echo the child's output, line by line, each whole (`say`), with a `[name]` prefix, and keep its last
        lines. Read in chunks, a line ends at `\n` or `\r` (a progress line rewritten with `\r` is a line each time)
        and one longer than `MAX_LINE` is cut: a child printing without a newline would otherwise grow bringup's
        memory without bound. Once bringup's own output is gone (a closed pipe), the child's is still read, so
        that the child never blocks on a full pipe."""
        assert self.process.stdout is not None
        pending, cutting = b'', False
        while chunk := self.process.stdout.read1(READ_CHUNK):
            *lines, pending = _LINE_END.split(pending + chunk)
            for line in lines:
                if not cutting:
                    self._emit(line)
                cutting = False
            if len(pending) > MAX_LINE:
                if not cutting:
                    self._emit(pending[:MAX_LINE] + f' [... cut: a line of over {MAX_LINE // 1024} KiB]'.encode())
                pending, cutting = b'', True
        if pending and not cutting:
            self._emit(pending)
        self.output_done.set()

    def _emit(self, data: bytes) -> None:
        line = data.decode(errors='replace')
        self.tail.append(line)
        if self.echo:
            self.echo = say(f'[{self.name}] {line}')

    def failure(self) -> str:
        """What went wrong, once the process has ended unexpectedly: one line, ending with the child's last line
        (its own output, shown above with its `[name]` prefix, has the rest)."""
        self.output_done.wait(2.0)  # its last lines explain the failure
        last = next((line.strip() for line in reversed(self.tail) if line.strip()), '')
        return f'{self.name} exited unexpectedly with code {self.process.returncode}' + (f': {last}' if last else '')


class Watchdog:
    """The process that stops the children if `bringup` dies without stopping them itself."""

    def __init__(self) -> None:
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'epuck_ros.bringup.watchdog', str(STOP_TIMEOUT)], stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True, start_new_session=True,
            env={k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'})

    def watch(self, pid: int) -> None:
        start = process_start_time(pid)
        if start is not None and self.process.stdin is not None:
            self.process.stdin.write(f'{pid} {start}\n')
            self.process.stdin.flush()

    def release(self) -> None:
        """Every child has been stopped: the watchdog ends without touching anything."""
        assert self.process.stdin is not None
        try:
            self.process.stdin.write('done\n')
            self.process.stdin.close()
        except OSError:
            pass
        self.process.wait()


class Children:
    """The run's child processes: started with both guards, stopped in a given order."""

    def __init__(self) -> None:
        self.started: list[Child] = []
        self._watchdog = Watchdog()

    def start(self, role: str, name: str, command: list[str]) -> Child:
        """Start `command` with its output forwarded. Its own session: the terminal's Ctrl-C reaches
        `bringup` only, which then stops the children in order."""
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True,
            preexec_fn=_die_with(os.getpid()),
            env=dict(os.environ, PYTHONUNBUFFERED='1', RCUTILS_COLORIZED_OUTPUT='0'))
        self._watchdog.watch(process.pid)
        child = Child(role, name, process)
        threading.Thread(target=child.forward_output, daemon=True).start()
        self.started.append(child)
        return child

    def dead(self) -> Child | None:
        """A child that has ended, if any."""
        return next((c for c in self.started if c.process.poll() is not None), None)

    def stop(self, order: tuple[str, ...], reported: Child | None = None,
             lenient: Child | None = None) -> tuple[list[str], list[str]]:
        """Ask each child to end (roles in `order`, a bounded wait each); returns (problems, notes). The `reported`
        child's end has been told already; the `lenient` child's unclean exit once asked to stop is only a note
        (a user's own script, whose shutdown is its own)."""
        problems, notes = [], []
        for child in sorted(self.started, key=lambda c: order.index(c.role)):
            running = child.process.poll() is None
            ended_by = escalate(child.process, STOP_SIGNALS)
            if ended_by is None:
                problems.append(f'{child.name} did not stop within {STOP_TIMEOUT:.0f} s of '
                                f'{" then ".join(signum.name for signum, _ in STOP_SIGNALS)} and was killed')
                continue
            if ended_by != STOP_SIGNALS[0][0]:
                notes.append(f'{child.name} ignored {STOP_SIGNALS[0][0].name} for {STOP_SIGNALS[0][1]:.0f} s and '
                             f'ended on {ended_by.name}')
            if child is not reported and child.process.returncode not in CLEAN_EXIT_CODES:
                message = f'{child.name} exited with code {child.process.returncode}'
                if child is lenient and running:
                    notes.append(f'{message} when asked to stop (see its output above)')
                else:
                    problems.append(message)
        self._watchdog.release()
        return problems, notes


def escalate(process: subprocess.Popen, steps: tuple[tuple[signal.Signals, float], ...]
             ) -> signal.Signals | None:
    """Send each signal of `steps` in turn, waiting its grace (wall seconds) for the process to end; SIGKILL after
    the last. Returns the signal it ended on (the first if it had already ended), None if it had to be killed."""
    for signum, grace in steps:
        if process.poll() is not None:
            return signum
        process.send_signal(signum)
        try:
            process.wait(grace)
            return signum
        except subprocess.TimeoutExpired:
            pass
    process.kill()
    process.wait()
    return None


def interrupt(process: subprocess.Popen, timeout: float, signum: int = signal.SIGINT) -> bool:
    """`signum` (Ctrl-C by default), then SIGKILL after `timeout` seconds; False if it had to be killed."""
    return escalate(process, ((signal.Signals(signum), timeout),)) is not None
