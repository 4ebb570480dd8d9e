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
"""

from __future__ import annotations

import ctypes
import hashlib
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

__all__ = ["DaskExecutor", "fingerprint", "LOCAL_CONFIG"]

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
        here and closed with the executor.
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

        # this process speaks for the cluster in one line (RgmcadError); distributed's own
        # complaints (reconnecting, lost workers, recomputed tasks) go to the scheduler's log
        logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
        self.address = scheduler
        self.max_batch = max_batch
        self.tasks_per_worker = tasks_per_worker
        self._counted = (-1e9, 1)
        self.expected = fingerprint()
        self._cluster = None
        try:
            if scheduler.startswith("local:"):
                n = _local_workers(scheduler)
                logging.getLogger("distributed").setLevel(logging.ERROR)
                with dask.config.set(LOCAL_CONFIG):
                        self._cluster = LocalCluster(n_workers=n, threads_per_worker=1,
                                                 processes=True,
                                                 scheduler_kwargs={"dashboard": False})
                self.client = Client(self._cluster, set_as_default=False)
            else:
                # Dask's table of every differing package: our fingerprint check below says
                # in one line what matters to results
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", VersionMismatchWarning)
                    self.client = Client(scheduler, timeout=connect_timeout,
                                         set_as_default=False)
        except (OSError, TimeoutError) as exc:
            self.close()
            raise RgmcadError(scheduler, "", "no Dask scheduler answers there "
                              f"({type(exc).__name__}); start one or check --scheduler") from None
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
                raise _refusal(self.address, where, version, self.expected)

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
            raise _lost(self.address, exc) from None
        return self._results(futures)

    def _results(self, futures):
        from distributed import KilledWorker

        try:
            for f in futures:
                try:
                    batch = f.result()
                except VersionRefused as exc:
                    raise RgmcadError(self.address, "", f"a worker runs another {exc}; "
                                      "install the client's rgmcad on every worker") from None
                except KilledWorker as exc:
                    raise RgmcadError(self.address, "", f"tasks killed their workers again and "
                                      f"again ({exc}); see the workers' logs") from None
                except RgmcadError:
                    raise
                except Exception as exc:
                    if _is_connection_loss(exc, self.client):
                        raise _lost(self.address, exc) from None
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


def _local_workers(scheduler: str) -> int:
    from rgmcad.runs.executor import max_workers

    try:
        n = int(scheduler.split(":", 1)[1])
    except ValueError:
        n = 0
    if not 1 <= n <= max_workers():
        raise RgmcadError(scheduler, "", f"local:N needs N from 1 to {max_workers()}")
    return n


def _refusal(address: str, where: str, version, expected: str) -> RgmcadError:
    runs = (f"cannot load rgmcad ({type(version).__name__}: {version})"
            if isinstance(version, BaseException) else f"runs rgmcad {version}")
    return RgmcadError(address, "", f"{where} {runs}, this client {expected}: refused; "
                       "install the client's rgmcad on the scheduler and every worker")


def _is_connection_loss(exc: BaseException, client) -> bool:
    from concurrent.futures import CancelledError

    from distributed.comm.core import CommClosedError

    return (isinstance(exc, (CancelledError, CommClosedError, OSError, TimeoutError))
            or client.status not in ("running", "connecting"))


def _lost(address: str, exc: BaseException) -> RgmcadError:
    return RgmcadError(address, "", f"the Dask scheduler went away ({type(exc).__name__}); "
                       "the simulations done are in the run directory: run the same command "
                       "again once a scheduler is back")
