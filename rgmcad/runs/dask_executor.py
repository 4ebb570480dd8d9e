"""Simulations on a Dask cluster (``--scheduler ADDRESS``, ``RGMCAD_SCHEDULER``, ``local:N``).

:class:`DaskExecutor` speaks the executor protocol of :mod:`rgmcad.runs.executor`
(``workers``, ``map``, ``map_context``, ``close``). Items go out in batches (several per
task: a Dask task costs about 5 ms of the client's and scheduler's CPU and 4 ms of its
worker's; :func:`task_size`) and come back in the order of the items, so a
seed gives the identical result here, on a process pool or serially.

What the workers need travels from the client: a :class:`~rgmcad.runs.problem.ContextPayload`
(the scenario's text, the part family files of ``--parts`` and the built parts, pickled; a
few hundred kB) is registered as a worker plugin under its SHA-256, so every worker, one
that joins later included, holds it; a task names the digest and the worker builds its
:class:`~rgmcad.runs.problem.ScenarioContext` from the payload once per thread (no shared
file system, nothing but rgmcad installed).

The scheduler and every worker must run this rgmcad (its version, a digest of its code and
the versions of the libraries that shape results, :func:`fingerprint`; the scheduler
unpickles every task graph): they are checked when the executor connects, and each task
checks again where it runs (a worker may join later); another version, or none, is refused
with one line (:class:`~rgmcad.errors.RgmcadError`). Each worker undoes the nanny's memory
trimming (:func:`_keep_freed_memory`). A worker that dies mid-run loses nothing: the
scheduler runs its tasks elsewhere. A scheduler that disappears stops the run with one line;
every finished simulation is in the run directory (on the client), so the same command
resumes once a scheduler and workers are back (a ``dask worker`` ends with its scheduler).

An address is checked before any connection: its form first
(:func:`~rgmcad.runs.executor.check_scheduler`), then a scheduler must answer a first question
within :data:`CONNECT_TIMEOUT` seconds (:func:`ask_scheduler`, asked in a loop of our own: a
Dask client that fails to connect hangs for twice its timeout when it is collected); an
address of another form, nothing answering there, or something that is not a scheduler is
one line naming ``--scheduler`` (or ``RGMCAD_SCHEDULER``).
"""

from __future__ import annotations

import asyncio
import ctypes
import hashlib
import struct
import threading
import time
import warnings
from collections.abc import Callable, Sequence
from functools import lru_cache, partial
from pathlib import Path

import dask
from distributed import WorkerPlugin
from distributed.versions import VersionMismatchWarning

from rgmcad.errors import RgmcadError

__all__ = ["DaskExecutor", "fingerprint", "LOCAL_CONFIG", "ask_scheduler", "CONNECT_TIMEOUT"]

LOCAL_CONFIG = {"distributed.worker.profile.enabled": False,
                "distributed.scheduler.worker-saturation": float("inf"),
                "distributed.admin.tick.interval": "500ms",
                "distributed.worker.memory.monitor-interval": "1s",
                "distributed.admin.system-monitor.interval": "2s"}
"""Dask settings of a ``local:N`` cluster: no statistical profiler (a thread sampling every
worker's stack each 10 ms), every task sent to a worker as soon as it is known rather than
when the worker asks for more (a round trip between two short simulations), and the
workers' periodic checks (event loop tick, memory and system monitors) 5-25 times rarer:
their wake-ups take the GIL from the simulation (about +7 % throughput on ballrun, 2
cores). Set them in a real cluster's configuration too (README, "Running on a cluster")."""

@lru_cache(maxsize=1)
def _code_digest() -> str:
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for f in sorted(root.rglob("*.py")):
        h.update(str(f.relative_to(root)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()[:12]


RESULT_PACKAGES = ("pybullet", "numpy", "scipy", "scikit-learn")
"""The libraries whose version can change a simulation or a fitted model: part of
:func:`fingerprint`."""


@lru_cache(maxsize=1)
def _package_versions() -> str:
    from importlib.metadata import PackageNotFoundError, version

    def installed(name: str) -> str:
        try:
            return version(name)
        except PackageNotFoundError:
            return "missing"

    return ", ".join(f"{p} {installed(p)}" for p in RESULT_PACKAGES)


def fingerprint() -> str:
    """This process's rgmcad: ``VERSION+CODE`` (version string, SHA-256 of its sources) and
    the versions of :data:`RESULT_PACKAGES`."""
    import rgmcad

    return f"{rgmcad.__version__}+{_code_digest()} ({_package_versions()})"


class VersionRefused(RuntimeError):
    """Raised on a worker whose rgmcad is not the client's."""


class _PayloadPlugin(WorkerPlugin):
    """A Dask worker plugin that only holds a context payload on every worker."""

    def __init__(self, payload):
        self.payload = payload

    def setup(self, worker):  # the payload is what a worker keeps
        _keep_freed_memory()


M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3  # <malloc.h>


@lru_cache(maxsize=1)
def _keep_freed_memory() -> None:
    """Undo, once in this worker process, the ``MALLOC_TRIM_THRESHOLD_=65536`` that a Dask
    nanny gives the processes it starts: with it glibc returns freed memory to the system at
    once and serves every block over 128 kB by its own ``mmap``, and a simulation, which
    builds and drops a physics world, spent 15-20 % more CPU (page faults, trims; 44 against
    37 ms per ballrun simulation, docs/decisions.md). The thresholds set are the highest that
    glibc's own adaptive default reaches (32 MiB, trim at twice that): a worker keeps at most
    that much freed memory for reuse."""
    try:
        libc = ctypes.CDLL(None)
        libc.mallopt(M_MMAP_THRESHOLD, 32 << 20)
        libc.mallopt(M_TRIM_THRESHOLD, 64 << 20)
    except (OSError, AttributeError):  # not glibc: nothing to undo
        pass


_LOCAL = threading.local()


def _context(name: str, expected: str):
    """This worker thread's context for the payload registered as ``name``."""
    mine = fingerprint()
    if mine != expected:
        raise VersionRefused(f"rgmcad {mine}, client {expected}")
    contexts = getattr(_LOCAL, "contexts", None)
    if contexts is None:
        contexts = _LOCAL.contexts = {}
    if name not in contexts:
        from distributed import get_worker

        _keep_freed_memory()
        contexts[name] = get_worker().plugins[name].payload.context()
    return contexts[name]


def _apply_batch(expected: str, fn: Callable, batch: Sequence) -> list:
    if fingerprint() != expected:
        raise VersionRefused(f"rgmcad {fingerprint()}, client {expected}")
    _keep_freed_memory()
    return [fn(item) for item in batch]


def _apply_context_batch(name: str, expected: str, fn: Callable, batch: Sequence) -> list:
    context = _context(name, expected)
    return [fn(context, item) for item in batch]


class DaskExecutor:
    """Runs tasks on a Dask cluster.

    Parameters
    ----------
    scheduler : str
        A scheduler's address (``tcp://host:8786``) or ``local:N``: a
        :class:`~distributed.LocalCluster` of N worker processes (one thread each), started
        here and closed with the executor. Its form is checked first
        (:func:`~rgmcad.runs.executor.check_scheduler`), then a scheduler must answer there
        within :data:`CONNECT_TIMEOUT` seconds; else one line (:class:`RgmcadError`) naming
        where the address was given (``--scheduler`` or ``RGMCAD_SCHEDULER``).
    connect_timeout : float, default 20
        Seconds the client has to connect once the scheduler has answered.
    payload : ContextPayload, optional
        What builds each worker's context (see the module docstring); needed by
        :meth:`map_context`.
    max_batch : int, default 8
        Most items per task.
    tasks_per_worker : int, default 1
        A call of ``map`` over n items makes about ``tasks_per_worker`` tasks per worker
        (:func:`task_size`): fewer, larger tasks than the process pool's 8 per worker, as
        a Dask task costs about 5 ms of the client's and the scheduler's CPU and 4 ms of
        its worker's against the pool's 0.1 ms; an unlucky split is evened out by the next
        batch, already submitted (tools/bench_cluster.py: 1 beat 2 on ballrun).
    """

    def __init__(self, scheduler: str, payload=None, max_batch: int = 8,
                 connect_timeout: float = 20.0, tasks_per_worker: int = 1):
        import logging

        from distributed import Client, LocalCluster

        from rgmcad.runs.executor import SchedulerAddress, check_scheduler

        if not isinstance(scheduler, SchedulerAddress):
            scheduler = check_scheduler(scheduler)  # its form, before any connection
        # this process speaks for the cluster in one line (RgmcadError); distributed's own
        # complaints (reconnecting, lost workers, recomputed tasks) go to the scheduler's log
        logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
        self.address, self.where = str(scheduler), scheduler.where
        self.max_batch = max_batch
        self.tasks_per_worker = tasks_per_worker
        self._counted = (-1e9, 1)
        self.expected = fingerprint()
        self._cluster = None
        if scheduler.startswith("local:"):
            logging.getLogger("distributed").setLevel(logging.ERROR)
            try:
                with dask.config.set(LOCAL_CONFIG):
                    self._cluster = LocalCluster(n_workers=int(scheduler[6:]), processes=True,
                                                 threads_per_worker=1,
                                                 scheduler_kwargs={"dashboard": False})
                self.client = Client(self._cluster, set_as_default=False)
            except Exception as exc:  # noqa: BLE001 - no processes, no ports: one line
                self.close()
                raise RgmcadError(self.where, self.address, "cannot start the local cluster "
                                  f"({type(exc).__name__}: {exc})") from None
        else:
            # a Client that fails to connect hangs for twice its timeout when collected:
            # first a short question, in a loop of our own, that anything there must answer
            _scheduler_answers(self.address, self.where)
            try:  # Dask's table of every differing package: our fingerprint check below says
                # in one line what matters to results
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", VersionMismatchWarning)
                    self.client = Client(self.address, timeout=connect_timeout,
                                         set_as_default=False)
            except Exception as exc:  # noqa: BLE001 - it answered the question, then not this
                self.close()
                raise RgmcadError(self.where, self.address, "the Dask scheduler there stopped "
                                  f"answering ({type(exc).__name__}); check it and run the same "
                                  "command again") from None
        try:
            self._check_versions()
            self.name = None
            if payload is not None:
                self.name = f"rgmcad-{payload.digest[:16]}"
                self.client.register_plugin(_PayloadPlugin(payload), name=self.name)
        except BaseException:
            self.close()
            raise

    @property
    def workers(self) -> int:
        """Worker threads in the cluster now (asked of the scheduler at most every 2 s: a
        round trip)."""
        now = time.monotonic()
        if now - self._counted[0] > 2.0:
            try:
                info = self.client.scheduler_info()["workers"]
                self._counted = (now, max(1, sum(w.get("nthreads", 1) for w in info.values())))
            except Exception:  # noqa: BLE001 - gone: the next task says so
                self._counted = (now, self._counted[1])
        return self._counted[1]

    def _check_versions(self) -> None:
        # the scheduler too: it unpickles every task graph, so it must import this rgmcad
        try:
            versions = {"the scheduler": self.client.run_on_scheduler(fingerprint)}
        except Exception as exc:  # noqa: BLE001 - its ImportError, pickled back to us
            versions = {"the scheduler": exc}
        workers = self.client.run(fingerprint, on_error="return")
        versions.update((f"worker {w}", v) for w, v in sorted(workers.items()))
        for where, version in versions.items():
            if version != self.expected:
                raise _refusal(self.where, self.address, where, version, self.expected)

    def map(self, fn, items):
        return self._submit(_apply_batch, (self.expected, fn), items)

    def map_context(self, fn, items):
        if self.name is None:
            raise ValueError("DaskExecutor.map_context needs a payload")
        return self._submit(_apply_context_batch, (self.name, self.expected, fn), items)

    def _submit(self, apply: Callable, args: tuple, items):
        items = list(items)
        size = task_size(len(items), self.tasks_per_worker * self.workers, self.max_batch)
        try:
            futures = self.client.map(partial(apply, *args),
                                      [items[i:i + size] for i in range(0, len(items), size)],
                                      pure=False) if items else []
        except Exception as exc:  # noqa: BLE001
            raise _lost(self.where, self.address, exc) from None
        return self._results(futures)

    def _results(self, futures):
        from distributed import KilledWorker

        try:
            for f in futures:
                try:
                    batch = f.result()
                except VersionRefused as exc:
                    raise RgmcadError(self.where, self.address, f"a worker runs another {exc}; "
                                      "install the client's rgmcad on every worker") from None
                except KilledWorker as exc:
                    raise RgmcadError(self.where, self.address, f"tasks killed their workers again and "
                                      f"again ({exc}); see the workers' logs") from None
                except RgmcadError:
                    raise
                except Exception as exc:
                    if _is_connection_loss(exc, self.client):
                        raise _lost(self.where, self.address, exc) from None
                    raise
                yield from batch
        finally:
            for f in futures:
                if not f.done():
                    f.cancel()

    def close(self) -> None:
        client, self.client = getattr(self, "client", None), None
        if client is not None:
            try:
                client.close(timeout=5)
            except Exception:  # noqa: BLE001, S110 - a scheduler already gone
                pass
        if self._cluster is not None:
            try:
                self._cluster.close(timeout=10)
            except Exception:  # noqa: BLE001, S110
                pass
            self._cluster = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def task_size(n: int, slots: int, max_batch: int) -> int:
    """Items per task for ``n`` items on ``slots`` (workers x tasks per worker): as many
    waves of one task per slot as tasks of at most ``max_batch`` items need, items spread
    evenly over them (1,500 items on 128 workers: 250 tasks of 6 in 2 waves, where tasks
    of 8 would make 188 tasks and 2 waves of 8)."""
    waves = max(1, -(-n // (slots * max_batch)))
    return max(1, -(-n // (slots * waves)))


CONNECT_TIMEOUT = 3.0
"""Seconds a scheduler has to answer a first question (``identity``: its kind and address)
before the executor gives up on it: a scheduler answers in milliseconds, even a busy one or
one across the world; nothing listening there (Dask tries again until the time is up), a
host that does not answer, or a name no DNS knows cost this long."""


_ASKED: dict[str, tuple[threading.Thread, dict, float]] = {}
"""Questions to schedulers under way: address -> (thread, its answer, when to stop waiting)."""


def ask_scheduler(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Start asking whatever listens at ``address`` what it is (``identity``), in a thread
    and an event loop of our own, for at most ``timeout`` seconds; the executor collects the
    answer. The CLI asks as soon as ``--scheduler`` is parsed, so the question runs while
    the command loads its scenario and parts."""
    if address in _ASKED:
        return

    async def ask():
        from distributed.comm import connect
        from distributed.security import Security

        comm = await connect(address, timeout=timeout,
                             **Security().get_connection_args("client"))
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    def run():
        try:
            _listens(address, timeout)  # Dask tries a refused connection again and again
            answer["reply"] = asyncio.run(asyncio.wait_for(ask(), timeout))
        except BaseException as exc:  # noqa: BLE001 - anything at all: said in one line
            answer["error"] = exc

    answer: dict = {}
    thread = threading.Thread(target=run, name="rgmcad-ask-scheduler", daemon=True)
    thread.start()
    # a DNS lookup may outlive the loop's own timeout: we stop waiting a little after it
    _ASKED[address] = (thread, answer, time.monotonic() + timeout + 1.0)


def _listens(address: str, timeout: float) -> None:
    """ConnectionRefusedError at once when nothing listens at a TCP ``address``."""
    import socket

    scheme, _, place = address.partition("://")
    if scheme in ("tcp", "tls", "ws", "wss"):
        host, _, port = place.rpartition(":")
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout).close()


def _scheduler_answers(address: str, where: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """Wait for the answer of :func:`ask_scheduler` (asked now if not yet); an
    :class:`RgmcadError` naming ``where`` unless a Dask scheduler answered."""
    ask_scheduler(address, timeout)
    thread, answer, deadline = _ASKED.pop(address)
    thread.join(max(0.0, deadline - time.monotonic()))
    error, reply = answer.get("error"), answer.get("reply")
    if not answer or isinstance(error, TimeoutError) or (
            isinstance(error, OSError) and "Timed out" in str(error)):
        why = (f"no Dask scheduler answers there within {timeout:g} s (nothing listens on "
               "that port, or the host is unreachable)")
    elif isinstance(error, OSError):
        why = f"no Dask scheduler answers there ({error.strerror or error})"
    elif isinstance(error, (MemoryError, struct.error)):  # a length read from garbage
        why = "what answers there does not speak Dask's protocol"
    elif error is not None:
        why = f"cannot talk to a Dask scheduler there ({type(error).__name__}: {error})"
    elif not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        kind = reply.get("type") if isinstance(reply, dict) else None
        why = (f"a Dask {kind} answers there, not the scheduler" if isinstance(kind, str)
               else "what answers there is no Dask scheduler")
    else:
        return
    raise RgmcadError(where, address, f"{why[:300]}; start one, or give the address the "
                      "scheduler printed (tcp://HOST:PORT)")


def _refusal(flag: str, address: str, where: str, version, expected: str) -> RgmcadError:
    runs = (f"cannot load rgmcad ({type(version).__name__}: {version})"
            if isinstance(version, BaseException) else f"runs rgmcad {version}")
    return RgmcadError(flag, address, f"{where} {runs}, this client {expected}: refused; "
                       "install the client's rgmcad on the scheduler and every worker")


def _is_connection_loss(exc: BaseException, client) -> bool:
    from concurrent.futures import CancelledError

    from distributed.comm.core import CommClosedError

    return (isinstance(exc, (CancelledError, CommClosedError, OSError, TimeoutError))
            or client.status not in ("running", "connecting"))


def _lost(flag: str, address: str, exc: BaseException) -> RgmcadError:
    return RgmcadError(flag, address, f"the Dask scheduler went away ({type(exc).__name__}); "
                       "the simulations done are in the run directory: run the same command "
                       "again once a scheduler is back")
