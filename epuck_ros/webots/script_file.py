"""A controller script's source, read as untrusted input (`untrusted_file`): the runner, a headless trial and a
sweep's spec all read it here, so a FIFO or /dev/zero named as a script is one line wherever it is named.

No ROS here: a sweep checks its scripts without importing rclpy.
"""
from __future__ import annotations

from pathlib import Path

from epuck_ros.untrusted_file import FileMissing, FileProblem, read_bounded

MAX_SCRIPT_BYTES = 1 << 20
"""A controller script larger than this is refused unread."""


def read_script(path: str | Path) -> bytes:
    """The script's bytes; FileProblem (not found, not a regular file, too large) otherwise."""
    return read_bounded(path, MAX_SCRIPT_BYTES)


__all__ = ['FileMissing', 'FileProblem', 'MAX_SCRIPT_BYTES', 'read_script']
