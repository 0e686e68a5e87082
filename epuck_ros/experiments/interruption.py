"""Ctrl-C and SIGTERM end a long command (`sweep`, `evolve`) the same way: what is done is kept, the end is said,
and the exit code is the one shells expect of a process a signal ended (128 + the signal: 130, 143), so that
`sweep ... && analyse` stops there.

SIGTERM is raised as `Terminated`, a KeyboardInterrupt, so every clean-up written for Ctrl-C (a trial's process
killed, the local cluster closed) runs for it too.
"""
from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType


class Terminated(KeyboardInterrupt):
    """SIGTERM arrived."""


def exit_code(interruption: KeyboardInterrupt) -> int:
    """128 + the signal that ended the command: 130 for Ctrl-C, 143 for SIGTERM."""
    return 128 + (signal.SIGTERM if isinstance(interruption, Terminated) else signal.SIGINT)


@contextmanager
def terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM raises Terminated in the main thread meanwhile (elsewhere nothing changes)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def raise_terminated(signum: int, frame: FrameType | None) -> None:
        raise Terminated()

    previous = signal.signal(signal.SIGTERM, raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def interrupts_ignored() -> Iterator[None]:
    """Ctrl-C and SIGTERM ignored meanwhile (the last writes: a signal would leave them half done), then as they
    were (a caller in the same process, a test say, keeps its own)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = [(number, signal.signal(number, signal.SIG_IGN)) for number in (signal.SIGINT, signal.SIGTERM)]
    try:
        yield
    finally:
        for number, handler in previous:
            signal.signal(number, handler)
