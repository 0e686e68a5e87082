"""How every command of the package ends, in one place (the README and each `--help` promise these codes).

0: done. 1 (`EXIT_FAILED`): the work failed after it began (a trial, a write, the Dask workers). 2
(`EXIT_BAD_INPUT`): bad input (an option, a file, a port), said in one line before anything is done, as argparse
does. A long command a signal ended exits 128 + the signal (`experiments.interruption`).
"""
from __future__ import annotations

import sys
from typing import NoReturn

EXIT_FAILED = 1
EXIT_BAD_INPUT = 2


def refuse(line: str) -> NoReturn:
    """The one line that says what is wrong (and how to mend it), on stderr, and exit 2."""
    print(line, file=sys.stderr)
    raise SystemExit(EXIT_BAD_INPUT)
