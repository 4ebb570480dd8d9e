"""Files written whole or not at all: a reader (or a run resumed after ``kill -9``) sees the
old content or the new one, never a torn half.

A write that fails (a full disk, a read-only one) raises the operating system's
:class:`OSError` naming the file it was writing (``exc.filename``; the ``write(2)`` that found
the disk full names none), so whoever reports it can say which file: :func:`naming`,
:func:`cannot_write`."""

from __future__ import annotations

import contextlib
import errno
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

__all__ = ["write_atomic", "write_json_atomic", "write_all", "append_whole", "naming",
           "cannot_write", "reason", "STORAGE_ERRORS"]

STORAGE_ERRORS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})
"""Errors of a write that say the storage, not the program, is at fault: full, over quota,
a file too large for it, read-only."""


@contextlib.contextmanager
def naming(path: str | Path) -> Iterator[None]:
    """An :class:`OSError` raised in the block names ``path`` as its file."""
    try:
        yield
    except OSError as exc:
        if exc.filename is not None and str(exc.filename) == str(path):
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc


def cannot_write(exc: OSError) -> str:
    """What to say of a failed write of ``exc.filename``: why, and what to do; nothing done
    is lost (each writer here leaves the old file, or a valid one)."""
    fix = ("free some space" if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
           else "make it writable")
    return (f"cannot be written ({reason(exc, False)}); {fix} and run the same command again: "
            "what was finished is kept")


def reason(exc: OSError | ValueError, file: bool = True) -> str:
    """What went wrong, without Python's decoration ("Permission denied: 'DIR/.lock'"); the
    file it names, after a colon, if ``file``."""
    if not isinstance(exc, OSError):
        return str(exc)
    where = f": {exc.filename}" if exc.filename and file else ""
    return f"{exc.strerror or exc}{where}"


def write_all(fd: int, data: bytes) -> None:
    """Write all of ``data`` to the descriptor ``fd`` (a short write goes on)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def append_whole(fd: int, data: bytes, path: str | Path) -> None:
    """Append ``data`` to the file open for appending on ``fd`` whole or not at all: a
    write that fails part way (a full disk) is cut off again, and the :class:`OSError`
    names ``path``."""
    with naming(path):
        end = os.lseek(fd, 0, os.SEEK_END)
        try:
            write_all(fd, data)
        except OSError:
            with contextlib.suppress(OSError):
                os.ftruncate(fd, end)  # shrinking needs no space
            raise


def _umask() -> int:
    mask = os.umask(0o022)  # reading the umask means setting it: put it straight back
    os.umask(mask)
    return mask


_NEW_FILE_MODE = 0o666 & ~_umask()  # read once, at import, before any thread starts


def write_atomic(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` to ``path`` through a temporary file in the same folder, flushed to
    disk and then renamed over ``path`` (atomic on POSIX and Windows)."""
    path = Path(path)
    if isinstance(data, str):
        data = data.encode("utf-8")
    with naming(path):
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            # mkstemp makes the file private (0600); the file written is the user's like any
            # other: its old mode if it existed, else what the umask allows (0644 under 022)
            try:
                mode = path.stat().st_mode & 0o7777
            except FileNotFoundError:
                mode = _NEW_FILE_MODE
            os.chmod(tmp, mode)
            try:
                write_all(fd, data)
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
    return path


def write_json_atomic(path: str | Path, data) -> Path:
    """:func:`write_atomic` of ``data`` as indented JSON with a final newline."""
    return write_atomic(path, json.dumps(data, indent=1) + "\n")

