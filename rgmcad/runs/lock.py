"""The lock of a run directory: one rgmcad process at a time, and never a dead one.

The lock is a POSIX record lock (:func:`fcntl.lockf`) on ``DIR/.lock``, held by the process
that opened the run directory and by no other:

* The kernel releases it when that process dies, however it dies (``kill -9`` included), so
  a lock can never outlive its owner on the same machine: a lock left by a dead process is
  simply free, and the next command takes it.
* A forked child does not inherit it. The ``flock`` lock rgmcad took before belongs to the
  open file, which pool workers shared through their inherited descriptor: after a ``kill
  -9`` of the main process its workers kept the directory locked until someone killed them
  (docs/decisions.md, "2026-12-01 — Run directory lock and pool workers").

Its file records the owner (``pid``, its start time, host, command) for the refusal message:
the process holding the lock is named, and checked against the kernel's list of locks
(``/proc/locks``) on Linux.

A POSIX lock belongs to a process, not to a descriptor: a second lock of the same file in the
same process succeeds, and closing *any* descriptor of the file releases the process's lock.
So this module keeps the locks this process holds (:data:`_HELD`), refuses a second lock of
the same directory here without opening its file, and never opens a lock file it holds.
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
import sys
import time
from pathlib import Path

__all__ = ["DirectoryLock", "LockedError", "LOCK_FILE"]

LOCK_FILE = ".lock"

_HELD: dict[tuple[int, int], DirectoryLock] = {}
"""The run-directory locks this process holds, by (device, inode) of the lock file."""


class LockedError(Exception):
    """The directory is locked by another process, or already by this one: the message says
    by which process."""


def _process_start(pid: int) -> int | None:
    """When ``pid`` started (clock ticks since boot; None where /proc is missing): with the
    pid, it names one process even after the pid is reused."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        return int(stat.rsplit(")", 1)[1].split()[19])
    except (OSError, ValueError, IndexError):
        return None


def _alive(pid: int, start: int | None) -> bool:
    """Whether the process ``pid`` that started at ``start`` still runs (a zombie does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return True  # no /proc here: the signal found it
    return fields[0] not in ("Z", "X") and (start is None or fields[19] == str(start))


def _kernel_holders(path: Path) -> list[int]:
    """The pids holding a POSIX lock on ``path`` according to /proc/locks (Linux; else [])."""
    try:
        st = path.stat()
        lines = Path("/proc/locks").read_text().splitlines()
    except OSError:
        return []
    inode = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    pids = []
    for line in lines:
        fields = line.split()
        if "POSIX" in fields and inode in fields and "->" not in fields:
            try:
                pids.append(int(fields[fields.index(inode) - 1]))
            except (ValueError, IndexError):
                pass
    return pids


def _describe(owner: dict) -> str:
    started = owner.get("started")
    when = (time.strftime(", running since %Y-%m-%d %H:%M:%S", time.localtime(started))
            if isinstance(started, (int, float)) else "")
    command = owner.get("command")
    return f"pid {owner.get('pid')}{when}" + (f": {command}" if command else "")


class DirectoryLock:
    """``DIR/.lock`` locked by this process, or :class:`LockedError`.

    Raises
    ------
    LockedError
        Another live process holds it (named in the message, with what it runs), or this
        process has the directory open already.
    OSError
        The lock file cannot be created or opened (a read-only or missing directory).
    """

    def __init__(self, directory: Path):
        self.path = Path(directory) / LOCK_FILE
        try:
            st = self.path.stat()
            if (st.st_dev, st.st_ino) in _HELD:  # opening the file would release our lock
                raise LockedError(f"this process (pid {os.getpid()}) has this run directory "
                                  "open already")
        except FileNotFoundError:
            pass
        # O_RDWR without O_TRUNC: the owner's record stays readable while it holds the lock
        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.lockf(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            message = self._holder_message()
            os.close(self.fd)
            raise LockedError(message) from None
        owner = {"pid": os.getpid(), "start": _process_start(os.getpid()),
                 "started": time.time(), "host": socket.gethostname(),
                 "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])[:300]}
        try:
            os.ftruncate(self.fd, 0)
            os.pwrite(self.fd, (json.dumps(owner) + "\n").encode(), 0)
            st = os.fstat(self.fd)
        except OSError:
            os.close(self.fd)
            raise
        self.key = (st.st_dev, st.st_ino)
        _HELD[self.key] = self

    def _holder_message(self) -> str:
        try:
            owner = json.loads(os.pread(self.fd, 4096, 0) or b"{}")
            owner = owner if isinstance(owner, dict) else {}
        except ValueError:
            owner = {}
        holders = _kernel_holders(self.path)
        pid = owner.get("pid")
        recorded_alive = isinstance(pid, int) and _alive(pid, owner.get("start"))
        if recorded_alive and (not holders or pid in holders):
            return (f"another rgmcad process ({_describe(owner)}) is using this run "
                    "directory; wait for it to finish, or choose another --run")
        who = (f"pid {', '.join(map(str, holders))}" if holders else "a process this machine "
               "cannot name (another machine sharing the folder?)")
        stale = f"; its recorded owner (pid {pid}) is no longer running" if pid else ""
        return (f"the run directory is locked by {who}{stale}; stop that process, or choose "
                "another --run")

    def release(self) -> None:
        """Unlock (closing the descriptor releases the lock)."""
        if self.fd is not None:
            _HELD.pop(self.key, None)
            os.close(self.fd)
            self.fd = None
