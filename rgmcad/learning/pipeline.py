"""The whole learning pipeline: explore, learn the success model, optimise, tolerances.

:func:`learn_and_optimize` runs paper sections 5-7 on a :class:`~rgmcad.learning.oracles.Problem`
and returns a frozen :class:`LearningResult`. Every simulation goes through
``problem.simulate`` in batches (optionally spread over an executor), is recorded with the
stage that asked for it, and counted. Given the same problem, settings and seed, the result
is identical.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from .dimensions import EventAnalysis
from .factorize import SPDModel, fit_spd
from .optimize import (
    OptimizationResult,
    maximize_robustness,
    place_unmodelled,
    placement_tolerance,
    start_points,
)
from .oracles import Label, Problem
from .sampling import explore
from .settings import LearningSettings

__all__ = ["Progress", "LearningResult", "learn_and_optimize"]

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Progress:
    """A progress report passed to ``on_progress``.

    Attributes
    ----------
    stage : str
        ``"exploration"``, ``"active:<event>"`` (or ``"active"`` for the full model),
        ``"model"``, ``"optimization"`` or ``"done"``.
    n_simulations : int
        Simulations run so far.
    message : str
    """

    stage: str
    n_simulations: int
    message: str = ""


@dataclass(frozen=True)
class LearningResult:
    """Everything :func:`learn_and_optimize` found.

    Attributes
    ----------
    x : (d,) float
        Optimised design vector in ``[0, 1]^d`` (valid: penetration exactly 0).
    probability : float
        Predicted P(success | x): the product of the factors (combined along the causal
        graph's alternatives where it has any-joins).
    event_probabilities : Mapping[str, float]
        Each factor's predicted probability at ``x`` (``{GLOBAL_EVENT: p}`` when not
        factorised).
    weakest_event : str or None
        The requirement with the lowest probability at ``x``: an event, or a group of
        alternatives ``any(...)`` (see :meth:`SPDModel.weakest_link`).
    tolerances : (d, 2) float
        Per coordinate, how far it may move down / up (normalised units) before the
        predicted probability falls below ``tolerance_ratio`` of ``probability`` or parts
        would overlap.
    x_start : (d,) float
        The start of the refinement (the best sample by predicted probability).
    probability_start : float
    X : (n, d) float
        Every simulated design vector, in order.
    labels : tuple of Label
        Their labels.
    stages : tuple of str
        The stage that asked for each simulation.
    n_simulations : Mapping[str, int]
        Simulations per stage.
    n_discarded : int
        Active-learning simulations whose label came back None for the factor being learnt.
    model : SPDModel
    analyses : Mapping[str, EventAnalysis]
        Per event: samples, success rate, quasi-determinism, mutual information, subspace.
    accuracy : Mapping[str, tuple[float, ...]]
        Cross-validated accuracy history of each learnt factor.
    optimization : OptimizationResult
    settings : LearningSettings
    exploration_iterations : int
        Adaptive iterations the exploration ran after its Sobol batch.
    exploration_stalled_at : int or None
        The iteration after which the exploration counted as stalled
        (:attr:`~.sampling.Exploration.stalled_at`), or None.
    """

    x: np.ndarray
    probability: float
    event_probabilities: Mapping[str, float]
    weakest_event: str | None
    tolerances: np.ndarray
    x_start: np.ndarray
    probability_start: float
    X: np.ndarray
    labels: tuple[Label, ...]
    stages: tuple[str, ...]
    n_simulations: Mapping[str, int]
    n_discarded: int
    model: SPDModel
    analyses: Mapping[str, EventAnalysis]
    accuracy: Mapping[str, tuple[float, ...]]
    optimization: OptimizationResult
    settings: LearningSettings
    exploration_iterations: int = 0
    exploration_stalled_at: int | None = None

    @property
    def n_total_simulations(self) -> int:
        """All simulations run."""
        return len(self.labels)

    @property
    def n_exploration_successes(self) -> int:
        """Global successes among the exploration's samples (the user's starts included)."""
        return sum(lab.success for lab, stage in zip(self.labels, self.stages, strict=True)
                   if stage == "exploration")

    def exploration_summary(self) -> dict:
        """The exploration in numbers (for ``result.json``): samples, global successes,
        adaptive iterations, and the iteration it stalled at (None if it never did)."""
        return {"samples": self.n_simulations.get("exploration", 0),
                "successes": self.n_exploration_successes,
                "iterations": self.exploration_iterations,
                "stalled_at": self.exploration_stalled_at}


class _Recorder:
    """Runs simulations in batches and keeps every labelled sample (internal)."""

    def __init__(self, problem: Problem, executor: Any, on_progress):
        self.problem = problem
        self.executor = executor
        self.on_progress = on_progress
        self.X: list[np.ndarray] = []
        self.labels: list[Label] = []
        self.stages: list[str] = []

    def __call__(self, X: np.ndarray, stage: str) -> list[Label]:
        return self.submit(X, stage)()

    def submit(self, X: np.ndarray, stage: str) -> Callable[[], list[Label]]:
        """Start simulating ``X``; the returned ``wait()`` gives its labels and records them.
        The problem's own ``submit`` (a problem that runs simulations elsewhere) starts them
        now; otherwise they run when waited for. Batches must be waited for in the order
        they were submitted."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if len(X) == 0:
            return list  # nothing to simulate: wait() gives []
        if self.executor is not None:  # one task per design vector; map keeps the order
            parts = self.executor.map(self.problem.simulate, [X[i : i + 1] for i in range(len(X))])

            def labels():
                return [lab for part in parts for lab in part]
        elif hasattr(self.problem, "submit"):
            labels = self.problem.submit(X)
        else:
            def labels():
                return list(self.problem.simulate(X))

        def wait() -> list[Label]:
            out = list(labels())
            if len(out) != len(X):
                raise ValueError(
                    f"problem.simulate returned {len(out)} labels for {len(X)} design vectors"
                )
            self.X.append(X)
            self.labels.extend(out)
            self.stages.extend([stage] * len(X))
            if self.on_progress is not None:
                self.on_progress(Progress(stage, len(self.labels), f"{len(X)} simulated"))
            return out

        return wait


def learn_and_optimize(
    problem: Problem,
    settings: LearningSettings | None = None,
    rng: np.random.Generator | int | None = None,
    *,
    on_progress: Callable[[Progress], None] | None = None,
    executor: Any = None,
    starts: np.ndarray | None = None,
) -> LearningResult:
    """Find a robust design vector for ``problem`` (paper sections 5-7).

    1. Exploration (Alg. 1): the user's start layouts if any, Sobol points, then mixtures
       around the most successful samples.
    2. Success model: factorised per event with active learning on each subspace (section
       6), or one global model when ``settings.factorized`` is False.
    3. Start at the explored sample with the highest predicted success (and, with
       ``refine_starts`` > 1, at the next best too); maximise the smooth minimum of the
       factors subject to ``penetration(x) <= 0`` (section 7); keep the best optimum.
    4. Placement tolerances at the optimum.

    Parameters
    ----------
    problem : Problem
    settings : LearningSettings, optional
        Defaults to ``LearningSettings()``.
    rng : numpy.random.Generator or int, optional
        The only source of randomness; an int seeds a new generator.
    on_progress : callable, optional
        Called with a :class:`Progress` after each simulation batch and each stage.
    executor : concurrent.futures.Executor-like, optional
        Anything with ``map(fn, iterable)``; simulations are submitted one design vector
        per task as ``executor.map(problem.simulate, ...)`` (so ``problem`` must be picklable
        for a process pool). Results keep their order, so the run stays deterministic.
    starts : (k, d) float in [0, 1]^d, optional
        Layouts to start from (the user's own): simulated first, so that the exploration
        grows around those that work (:func:`~.sampling.explore`). None: the paper's method,
        bit for bit.

    Returns
    -------
    LearningResult
    """
    settings = settings or LearningSettings()
    rng = np.random.default_rng(rng)
    record = _Recorder(problem, executor, on_progress)

    def report(stage: str, message: str) -> None:
        logger.info("%s: %s", stage, message)
        if on_progress is not None:
            on_progress(Progress(stage, len(record.labels), message))

    exploration = explore(
        problem, settings, rng, simulate=lambda X: record(X, "exploration"),
        submit=lambda X: record.submit(X, "exploration"), starts=starts,
    )
    smallest_step = min(exploration.step_scales, default=1.0)
    report(
        "exploration",
        f"{len(exploration.labels)} samples, {exploration.n_global_successes} global successes"
        + (f"; step down to {smallest_step:.2f} of the paper's" if smallest_step < 1 else "")
        + (f"; stalled at iteration {exploration.stalled_at}, newest samples first from then"
           if exploration.stalled_at is not None else ""),
    )

    fit = fit_spd(
        exploration.X, exploration.labels, problem.event_parents, problem.validity, record,
        settings, rng, any_joins=problem.any_joins,
    )
    model = fit.model
    report("model", f"learnt factors: {list(model.learned_events)}")

    X_explored = exploration.X
    valid_rows = [i for i, lab in enumerate(exploration.labels) if lab.valid]
    rows = start_points(model, X_explored[valid_rows], settings)
    x0 = X_explored[valid_rows[rows[0]]]
    opt = None
    for row in rows:  # the refinement costs no simulation: several starts are cheap
        found = maximize_robustness(model, problem.penetration,
                                    X_explored[valid_rows[row]], settings)
        if opt is None or found.objective > opt.objective:
            opt = found
    report("optimization", f"objective {opt.objective_start:.4f} -> {opt.objective:.4f}")

    x = opt.x
    if settings.unmodelled_at == "median":  # the run's successes, so far
        won = [k for k, lab in enumerate(record.labels) if lab.success]
        x = place_unmodelled(model, x, np.vstack(record.X)[won], problem.penetration)
    per_event = {e: float(p[0]) for e, p in model.event_probabilities(x).items()}
    probability = float(model.success_proba(x)[0])
    weakest, _ = model.weakest_link(x)
    tolerances = placement_tolerance(model, x, settings, problem.validity)

    counts: dict[str, int] = {}
    for st in record.stages:
        counts[st] = counts.get(st, 0) + 1
    n_discarded = sum(fit.n_simulations.values()) - sum(fit.n_labelled.values())
    X_all = np.vstack(record.X) if record.X else np.empty((0, problem.dimension))
    result = LearningResult(
        x=x,
        probability=probability,
        event_probabilities=per_event,
        weakest_event=weakest,
        tolerances=tolerances,
        x_start=x0,
        probability_start=float(model.success_proba(x0)[0]),
        X=X_all,
        labels=tuple(record.labels),
        stages=tuple(record.stages),
        n_simulations=counts,
        n_discarded=int(n_discarded),
        model=model,
        analyses=fit.analyses,
        accuracy=fit.accuracy,
        optimization=opt,
        settings=settings,
        exploration_iterations=exploration.n_iterations,
        exploration_stalled_at=exploration.stalled_at,
    )
    report("done", f"P(success) {result.probability:.4f}, weakest {weakest!r}")
    return result

