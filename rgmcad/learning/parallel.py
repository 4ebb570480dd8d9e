"""Where the learner's independent jobs run: grid-search folds, calibration folds and mutual
information estimates.

By default they run in this process, or in joblib's processes when ``n_jobs`` > 1. Inside
``with jobs_on(executor):`` they go to that executor (:mod:`rgmcad.runs.executor`) instead.
``rgmcad optimize`` lends the learner its simulation pool this way: the pool is idle while
the models train, and its workers were forked after scikit-learn was imported, while joblib's
processes are slow to start (they import scikit-learn again) and keep that memory for the
whole run. See docs/decisions.md, "Learner overheads: jobs on the simulation pool, no
check_array".

Where a job runs never changes its result: every job is a pure function of its arguments.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from functools import partial
from typing import Any

__all__ = ["jobs_on", "parallel_map"]

_EXECUTOR: ContextVar[Any] = ContextVar("rgmcad_learning_executor", default=None)


@contextmanager
def jobs_on(executor) -> Iterator[None]:
    """Run the learner's parallel jobs on ``executor`` (anything with ``workers`` and
    ``map(fn, items)``, such as :class:`rgmcad.runs.executor.PoolExecutor`) inside the block."""
    token = _EXECUTOR.set(executor)
    try:
        yield
    finally:
        _EXECUTOR.reset(token)


def _call(fn: Callable, args: Sequence) -> Any:
    return fn(*args)


def parallel_map(fn: Callable, jobs: Sequence[Sequence], n_jobs: int | None = None) -> list:
    """``[fn(*job) for job in jobs]``, in that order, wherever jobs run now (see the module
    docstring). ``fn`` must be a module-level function for the processes."""
    jobs = list(jobs)
    executor = _EXECUTOR.get()
    if len(jobs) > 1 and executor is not None and executor.workers > 1:
        return list(executor.map(partial(_call, fn), jobs))
    if len(jobs) > 1 and n_jobs is not None and n_jobs > 1 and executor is None:
        from joblib import Parallel, delayed

        return Parallel(n_jobs=n_jobs)(delayed(fn)(*job) for job in jobs)
    return [fn(*job) for job in jobs]
