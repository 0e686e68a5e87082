"""How every command of the package ends, in one place (the README and each `--help` promise these codes).

0: done. 1 (`EXIT_FAILED`): the work failed after it began (a trial, a write, the Dask workers). 2
(`EXIT_BAD_INPUT`): bad input (an option, a file, a port), said in one line before anything is done, as argparse
does. A long command a signal ended exits 128 + the signal (`experiments.interruption`).
"""
from __future__ import annotations

import atexit
import signal
import sys
from typing import NoReturn

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


def refuse(line: str) -> NoReturn:
    """The one line that says what is wrong (and how to mend it), on stderr, and exit 2."""
    print(line, file=sys.stderr)
    raise SystemExit(EXIT_BAD_INPUT)


def ignore_ctrl_c_at_exit() -> None:
    """Once the program has returned, Ctrl-C is ignored. Python's exit gives SIGINT its default action back, and the
    exit of a process with DDS participants or a Dask cluster takes a while: a Ctrl-C that came then, as the command
    was ending by itself with its work done, ended it with status -2 instead of 0 (`bag play` and `sweep` in loaded
    suite runs). Registered with atexit, so a caller in the same process (a test) keeps its own handler."""
    atexit.register(signal.signal, signal.SIGINT, signal.SIG_IGN)
