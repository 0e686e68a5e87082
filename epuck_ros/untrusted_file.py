"""Files we did not write (worlds, sweep specs, controller scripts, a table to resume): read only if they are
regular files, opened without blocking, and (but for a table read row by row) of bounded size, so a FIFO,
/dev/zero, /dev/urandom or a link to one is one line, not a hang or gigabytes of memory."""
from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import BinaryIO


class FileProblem(ValueError):
    """Why a file was not read, without its path (the caller names the file, or the field that named it)."""


class FileMissing(FileProblem):
    """There is no such file."""


def open_regular(path: str | Path) -> BinaryIO:
    """`path` opened for reading if it is a regular file (links followed); FileProblem otherwise."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, 'O_NONBLOCK', 0))   # a FIFO opens at once, then is refused
    except FileNotFoundError:
        raise FileMissing('file not found') from None
    except OSError as error:
        raise FileProblem(f'cannot read the file: {error.strerror}') from None
    except ValueError:   # os.open's "embedded null byte"
        raise FileProblem('cannot read the file: its name holds a NUL byte') from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise FileProblem('cannot read the file: not a regular file (a directory, pipe or device)')
        return os.fdopen(os.dup(fd), 'rb')
    except OSError as error:
        raise FileProblem(f'cannot read the file: {error.strerror}') from None
    finally:
        os.close(fd)


def read_bounded(path: str | Path, limit: int) -> bytes:
    """The bytes of `path`: a regular file of at most `limit` bytes, or FileProblem."""
    with open_regular(path) as file:
        try:
            size = os.fstat(file.fileno()).st_size
            data = file.read(limit + 1) if size <= limit else b''
        except OSError as error:
            raise FileProblem(f'cannot read the file: {error.strerror}') from None
    if size > limit:
        raise FileProblem(f'file too large ({size} bytes, at most {limit})')
    if len(data) > limit:   # it grew since
        raise FileProblem(f'file too large (more than {limit} bytes)')
    return data
