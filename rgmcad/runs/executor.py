"""Where simulations run: one small interface, a serial and a process-pool implementation.

An executor has ``map(fn, items)``: it applies ``fn`` to every item and yields the results
in the order of ``items``, as soon as each is available. ``fn`` must be picklable for the
pool (a module-level function or a bound method of a picklable object). The pool sends
items in batches (several per task: a task costs a few milliseconds of pickling and
scheduling, a simulation 30-150 ms). Results never depend on the number of workers: the
simulator is deterministic and the order is kept.

An executor's ``initializer(*initargs)`` runs once in every process that runs its tasks
(this one for the serial executor, each worker for the pool) and returns that process's
*context*: a :class:`~rgmcad.runs.problem.ScenarioContext` that loaded the scenario, its
parts and a physics engine once. ``map_context(fn, items)`` calls ``fn(context, item)``.

Pool workers die with the process that made the pool, even when it is killed with
``kill -9`` (which runs no clean-up): on Linux the kernel sends them SIGKILL when it dies
(``PR_SET_PDEATHSIG``), and on every system a thread in each worker exits it when its
parent changes. They also drop the descriptors the parent marked with :func:`parent_only`
(the run directory's simulation file and lock), which a forked worker would otherwise keep
open. So a killed ``rgmcad optimize`` leaves nothing running behind it
(docs/decisions.md, "2026-12-01 — Run directory lock and pool workers").

A Dask cluster is one more such class (:class:`rgmcad.runs.dask_executor.DaskExecutor`,
``make_executor(..., scheduler=ADDRESS)``): its workers build their context from a payload
sent by the client instead of an initializer run there.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from functools import partial
from typing import Any, Protocol

__all__ = ["Executor", "SerialExecutor", "PoolExecutor", "make_executor", "default_workers",
           "max_workers", "map_blocks", "parent_only", "scheduler_from_env", "SCHEDULER_ENV",
           "SchedulerAddress", "check_scheduler"]

SCHEDULER_ENV = "RGMCAD_SCHEDULER"
SCHEDULER_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx", "inproc")
"""The address schemes of dask.distributed's comms (``distributed.comm.registry``); an
address without one is ``tcp``, as Dask reads it."""


class SchedulerAddress(str):
    """A checked scheduler address (:func:`check_scheduler`) that remembers where it was
    given (``--scheduler`` or ``RGMCAD_SCHEDULER``), so an error about it names that."""

    where = "--scheduler"


def scheduler_from_env(scheduler: str | None) -> SchedulerAddress | None:
    """``scheduler``, else the environment's ``RGMCAD_SCHEDULER`` (unset or empty: None, no
    Dask), checked by :func:`check_scheduler` (an empty ``scheduler`` is refused)."""
    if isinstance(scheduler, SchedulerAddress):
        return scheduler
    if scheduler is not None:
        return check_scheduler(scheduler, "--scheduler")
    given = os.environ.get(SCHEDULER_ENV)
    return check_scheduler(given, SCHEDULER_ENV) if given else None


def check_scheduler(address: str, where: str = "--scheduler") -> SchedulerAddress:
    """``address`` if it has the form of a Dask scheduler's address: ``SCHEME://HOST:PORT``
    (scheme one of :data:`SCHEDULER_SCHEMES` but inproc, which takes any location; a bare
    ``HOST:PORT`` is tcp), ``HOST`` a name, an IPv4 address or an IPv6 one in brackets,
    ``PORT`` 1 to 65535; or ``local:N``, N from 1 to :func:`max_workers`. Checked before any
    connection, without importing Dask; else a :class:`~rgmcad.errors.UsageError` naming
    ``where``. Whether a scheduler answers there is the executor's to find out."""
    from rgmcad.errors import UsageError

    text = address if isinstance(address, str) else ""
    allowed = (f"expected a Dask scheduler's address, SCHEME://HOST:PORT with SCHEME one of "
               f"{', '.join(SCHEDULER_SCHEMES[:-1])} (e.g. tcp://10.0.0.5:8786), or local:N "
               f"(N worker processes here, 1 to {max_workers()})")
    if text.lower().startswith("local:"):
        n = text[6:]
        if not (n.isascii() and n.isdigit() and 1 <= int(n) <= max_workers()):
            raise UsageError(where, repr(text), f"local:N needs N from 1 to {max_workers()}")
        text = f"local:{int(n)}"
    else:
        scheme, sep, place = text.partition("://")
        scheme, place = (scheme.lower(), place) if sep else ("tcp", text)
        if scheme not in SCHEDULER_SCHEMES:
            raise UsageError(where, repr(text), f"unknown scheme {scheme!r}; {allowed}")
        if not place or not place.isprintable() or any(c.isspace() for c in place):
            raise UsageError(where, repr(text), allowed)
        if scheme != "inproc":
            problem = _host_port_problem(place)
            if problem:
                raise UsageError(where, repr(text), f"{problem}; {allowed}")
        text = f"{scheme}://{place}"
    checked = SchedulerAddress(text)
    checked.where = where
    return checked


def _host_port_problem(place: str) -> str | None:
    """What is wrong with ``HOST:PORT`` (None: nothing)."""
    import ipaddress
    import re

    host, sep, port = place.rpartition(":")
    if not sep or not host:
        return "expected HOST:PORT after the scheme"
    if not (port.isascii() and port.isdigit() and 1 <= int(port) <= 65535):
        return f"port {port!r}: expected a number from 1 to 65535"
    if host.startswith("[") and host.endswith("]"):
        try:
            ipaddress.IPv6Address(host[1:-1])
            return None
        except ValueError:
            return f"host {host!r}: not an IPv6 address"
    try:
        name = host.encode("idna").decode("ascii")  # a name in any script, as DNS spells it
    except UnicodeError:
        return f"host {host!r}: not a host name"
    labels = name.rstrip(".").split(".")
    if len(name) > 253 or not all(re.fullmatch(r"[A-Za-z0-9_]([A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?",
                                               label) for label in labels):
        return f"host {host!r}: not a host name or address"
    return None


class Executor(Protocol):
    """Runs ``fn`` over items, keeping their order."""

    workers: int

    def map(self, fn: Callable[[Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        """``fn(item)`` for every item, yielded in the order of ``items``."""
        ...

    def map_context(self, fn: Callable[[Any, Any], Any], items: Iterable[Any]) -> Iterator[Any]:
        """``fn(context, item)`` for every item, in order, with the context of the process
        that runs it (what the executor's initializer returned there)."""
        ...

    def close(self) -> None:
        """Release the workers."""
        ...


def default_workers() -> int:
    """The CPUs this process may use."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def max_workers() -> int:
    """The most worker processes a pool may have: four per CPU, at most 256 (more only
    costs memory and start-up time; results never depend on the number)."""
    return max(1, min(256, 4 * (os.cpu_count() or 1)))


_PARENT_ONLY: set[int] = set()
"""Descriptors of this process that its pool workers must not keep (see :func:`parent_only`)."""


def parent_only(fd: int, keep: bool = True) -> None:
    """Mark the descriptor ``fd`` as this process's alone (``keep=False``: unmark it, before
    closing it): a pool worker forked later points its copy at ``/dev/null`` when it
    starts, so it holds no file of its parent's (a run directory's journal, its lock)."""
    if keep:
        _PARENT_ONLY.add(fd)
    else:
        _PARENT_ONLY.discard(fd)


class SerialExecutor:
    """Runs everything in this process; ``initializer(*initargs)`` runs once, first, and
    gives :attr:`context`."""

    workers = 1

    def __init__(self, initializer: Callable | None = None, initargs: Sequence = ()):
        self.context = initializer(*initargs) if initializer is not None else None

    def map(self, fn, items):
        return map(fn, items)

    def map_context(self, fn, items):
        return map(partial(fn, self.context), items)

    def close(self) -> None:
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _apply_batch(fn: Callable, batch: Sequence) -> list:
    return [fn(item) for item in batch]


_CONTEXT = None
"""In a pool's worker process, what the pool's initializer returned there: the one value a
worker process exists to keep between tasks, handed to each task of ``map_context``."""


def _apply_context_batch(fn: Callable, batch: Sequence) -> list:
    return [fn(_CONTEXT, item) for item in batch]


PR_SET_PDEATHSIG = 1  # <linux/prctl.h>


def _watch_parent(parent: int, interval: float = 1.0) -> None:
    """Exit this worker once its parent is gone (the thread's whole job)."""
    while os.getppid() == parent:
        time.sleep(interval)
    os._exit(1)


def _tie_to_parent(parent: int) -> None:
    """Make this worker die with ``parent`` and drop the files its parent kept to itself."""
    if sys.platform.startswith("linux"):
        try:  # SIGKILL when the thread that forked this process ends: the parent's main thread
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before this worker could ask to follow it
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent,), name="rgmcad-parent-watch",
                     daemon=True).start()
    if _PARENT_ONLY:  # inherited through fork; same numbers, now /dev/null
        null = os.open(os.devnull, os.O_RDWR)
        for fd in _PARENT_ONLY:
            try:
                os.dup2(null, fd, inheritable=False)
            except OSError:
                pass
        os.close(null)
        _PARENT_ONLY.clear()


def _start_worker(parent: int, threads: int, initializer: Callable | None,
                  initargs: Sequence) -> None:
    """Worker start: die with ``parent`` (:func:`_tie_to_parent`), cap the BLAS and OpenMP
    threads of numpy and scikit-learn at ``threads`` (each worker otherwise starts one per
    CPU, and the workers oversubscribe the cores; the cap stays when the limiter object
    goes), then the caller's initializer, whose result is the worker's context."""
    global _CONTEXT
    _tie_to_parent(os.getppid() if parent < 0 else parent)
    # Ctrl-C in a terminal signals the whole process group: a worker interrupted inside the
    # pool's queue can leave its lock held (the parent then waits forever) or die mid-task
    # (a broken pool, a traceback); the parent alone handles it and ends the workers
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from threadpoolctl import threadpool_limits

    threadpool_limits(limits=threads)
    if initializer is not None:
        _CONTEXT = initializer(*initargs)


class PoolExecutor:
    """A :class:`concurrent.futures.ProcessPoolExecutor` that batches items into tasks.

    Parameters
    ----------
    workers : int
        Worker processes.
    initializer, initargs
        Run once in each worker when it starts (load the scenario and its parts there),
        after the worker's BLAS and OpenMP threads are capped at ``CPUs // workers``; the
        result is the worker's context (see :meth:`map_context`).
    max_batch : int, default 8
        Most items per task. A call of ``map`` over n items makes tasks of
        ``ceil(n / (8 workers))`` items (at most ``max_batch``), so each worker gets about
        eight tasks: few enough that scheduling costs little, enough that a slow item does not
        leave the other workers idle for long. The learner's batches of 10 simulations thus go
        one per task (docs/decisions.md).

    The workers start here, all at once, in this thread: on Linux a worker dies when the
    thread that started it ends, so they must not start in a thread that may end first.
    """

    def __init__(self, workers: int, initializer: Callable | None = None,
                 initargs: Sequence = (), max_batch: int = 8):
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.workers = workers
        self.max_batch = max_batch
        threads = max(1, default_workers() // workers)
        context = multiprocessing.get_context()
        # a forkserver's children are the server's, which dies with this process: -1 says
        # "the parent you start with"
        parent = -1 if context.get_start_method() == "forkserver" else os.getpid()
        self._pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker,
                                         initargs=(parent, threads, initializer,
                                                   tuple(initargs)))
        self._pool.submit(int)  # starts every worker now (see above)
        self._futures: list = []

    def map(self, fn, items):
        return self._submit(_apply_batch, fn, items)

    def map_context(self, fn, items):
        return self._submit(_apply_context_batch, fn, items)

    def _submit(self, apply: Callable, fn: Callable, items):
        items = list(items)
        size = max(1, min(self.max_batch, -(-len(items) // (8 * self.workers))))
        futures = [self._pool.submit(apply, fn, items[i:i + size])
                   for i in range(0, len(items), size)]
        self._futures = [f for f in self._futures if not f.done()] + futures
        return self._results(futures)

    @staticmethod
    def _results(futures):
        try:
            for f in futures:
                yield from f.result()
        finally:  # abandoned early (an error, a closed generator): drop what has not started
            for f in futures:
                f.cancel()

    def close(self) -> None:
        """Shut the pool down; tasks still running (the caller gave up on them: an error,
        Ctrl-C) are not waited for, their workers are ended."""
        if any(not f.done() for f in self._futures):
            for process in list((getattr(self._pool, "_processes", None) or {}).values()):
                process.terminate()
        self._pool.shutdown(wait=True, cancel_futures=True)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def map_blocks(executor, fn: Callable[[Any, Any], Any], X) -> Any:
    """``fn(context, rows) -> (k,) array`` over the rows of ``X``, one contiguous block per
    worker, results concatenated in order: for cheap per-row work (a validity test takes
    under a millisecond) that per-row tasks would spend more time scheduling than doing."""
    import numpy as np

    X = np.atleast_2d(np.asarray(X, dtype=float))
    blocks = max(1, min(len(X), executor.workers))
    return np.concatenate([np.asarray(r) for r in
                           executor.map_context(fn, np.array_split(X, blocks))])


def make_executor(workers: int | None, initializer: Callable | None = None,
                  initargs: Sequence = (), scheduler: str | None = None,
                  payload: Callable | None = None):
    """A serial executor for one worker, a process pool otherwise (None: every CPU); with
    ``scheduler`` (an address or ``local:N``), a Dask executor whose workers build their
    context from ``payload()`` (a :class:`~rgmcad.runs.problem.ContextPayload`), ``workers``
    then unused."""
    if scheduler:
        from rgmcad.runs.dask_executor import DaskExecutor

        return DaskExecutor(scheduler, payload() if payload is not None else None)
    n = default_workers() if workers is None else int(workers)
    if n <= 1:
        return SerialExecutor(initializer, initargs)
    return PoolExecutor(n, initializer, initargs)
