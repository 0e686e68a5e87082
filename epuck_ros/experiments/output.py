"""A command's output folder (`sweep -o OUT`, `evolve -o OUT`): made, held by one command at a time, and written
file by file, each whole or not at all.

Two commands writing into one folder at once lose each other's rows, so the folder is locked (flock on the folder
itself, released when the process ends, however it ends) and a second command is refused with one line. A file is
written beside its place and renamed over it: a reader never sees half of it, and a FIFO or a link left in its
place is replaced, not written through.
"""
from __future__ import annotations

import errno
import fcntl
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO


class OutputError(RuntimeError):
    """The folder cannot be used; the message names it and says why."""


class OutputFolder:
    """`-o PATH`: checked and held before anything is written (`check`, `lock`), made (`make`), written
    (`replace`)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fd: int | None = None

    def fail(self, problem: str) -> OutputError:
        return OutputError(f'-o {self.path}: {problem}')

    def check(self) -> None:
        """What can be said without writing anything: a path that is no folder, or one under a file."""
        try:
            if self.path.exists() and not self.path.is_dir():
                raise self.fail('not a folder')
            for parent in self.path.parents:
                if parent.exists():
                    if not parent.is_dir():
                        raise self.fail(f'{parent} is not a folder')
                    break
        except (OSError, ValueError) as error:   # ValueError: a NUL in the name
            raise self.fail(str(getattr(error, 'strerror', None) or error)) from None

    def lock(self) -> None:
        """Hold the folder if it exists (nothing is written): OutputError when another command holds it."""
        self.check()
        if self._fd is not None or not self.path.is_dir():
            return
        try:
            self._fd = os.open(self.path, os.O_RDONLY | os.O_DIRECTORY)
        except OSError as error:
            raise self.fail(f'cannot open the folder: {error.strerror}') from None
        try:
            fcntl.flock(self._fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
                self.close()
                raise self.fail('another sweep or evolve is writing there (it holds the folder\'s lock): wait for '
                                'it to end, or choose another folder') from None
            # a file system without flock (some network ones): go on unlocked

    def make(self) -> None:
        """Make the folder and hold it (`lock`), and see that files can be made there."""
        self.check()
        try:
            self.path.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise self.fail(f'cannot make the folder: {error.strerror}') from None
        self.lock()
        self.replace('.write-test', lambda out: None, keep=False)

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> OutputFolder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def replace(self, name: str, write: Callable[[BinaryIO], None], keep: bool = True) -> Path:
        """Write the file `name` whole: `write(stream)` into a new file beside it, then renamed over `name`
        (`keep=False`: removed instead, a test that the folder takes files). OutputError when that fails."""
        target = self.path / name
        try:
            fd, partial = tempfile.mkstemp(dir=self.path, prefix=f'.{name}.', suffix='.partial')
        except OSError as error:
            raise self.fail(f'cannot write there: {error.strerror}') from None
        try:
            with os.fdopen(fd, 'wb') as out:
                write(out)
            if keep:
                os.replace(partial, target)
        except OSError as error:
            raise self.fail(f'cannot write {name}: {error.strerror}') from None
        finally:
            if os.path.lexists(partial):
                os.unlink(partial)
        return target
