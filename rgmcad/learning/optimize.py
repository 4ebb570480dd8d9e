"""Layout optimisation on the learnt model (paper section 7) and placement tolerances.

The refinement maximises the smooth minimum of the per-event probabilities
(:meth:`SPDModel.objective`) over ``[0, 1]^d`` subject to ``penetration(x) <= 0``, starting
from the sample with the highest predicted success (the product of the factors). By
default each factor's probability is first averaged over a fixed design of errors
(:mod:`rgmcad.learning.errors`: Gaussian placement errors of ``placement_noise``, or the
errors of global robustness up to ``error_radius``; see
:class:`~rgmcad.learning.settings.LearningSettings`), i.e. the expected success of the
layout when it is built with such errors; no errors give the paper's objective.

The penetration is not differentiable (it is 0 on the whole valid set and grows like a
distance inside the invalid set), so the constraint is handled by nlopt's derivative-free
COBYLA by default; ``optimizer="auglag"`` runs an augmented Lagrangian (LD_AUGLAG) around
L-BFGS with the analytic objective gradient and forward finite differences of the
penetration, ``optimizer="slsqp"`` nlopt's SLSQP with the same gradients (the authors'
method, via SciPy). Whatever the method, every evaluated point is recorded and the result is
the best one whose penetration was exactly 0 (the start point at worst).

Why COBYLA: the penetration is flat (zero gradient) on the valid side, so gradient methods
see the constraint only after crossing it; COBYLA's linear models of the constraint, built
from points on both sides, do not depend on derivatives. It reached the constrained optimum
reliably and with the fewest penetration calls of the three; see docs/decisions.md,
"Refinement with COBYLA, averaged over placement errors".
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass

import nlopt
import numpy as np

from .errors import design_from_settings, expected_success
from .factorize import SPDModel
from .settings import LearningSettings

__all__ = [
    "OptimizationResult",
    "start_point",
    "start_points",
    "maximize_robustness",
    "overlap_ends",
    "placement_tolerance",
    "place_unmodelled",
]

logger = logging.getLogger(__name__)

PenetrationFn = Callable[[np.ndarray], float]

_ALGORITHMS = {"cobyla": nlopt.LN_COBYLA, "auglag": nlopt.LD_AUGLAG, "slsqp": nlopt.LD_SLSQP}


@dataclass(frozen=True)
class OptimizationResult:
    """Result of :func:`maximize_robustness`.

    Attributes
    ----------
    x : (d,) float
        Best valid point found (penetration exactly 0).
    objective : float
        Smooth minimum of the factors at ``x`` (of their averages over the placement
        errors when ``placement_noise > 0``).
    x_start : (d,) float
    objective_start : float
    n_evaluations : int
        Objective evaluations.
    n_penetration_calls : int
        Penetration evaluations (distinct points).
    status : str
        nlopt's stop reason, or the exception it raised.
    """

    x: np.ndarray
    objective: float
    x_start: np.ndarray
    objective_start: float
    n_evaluations: int
    n_penetration_calls: int
    status: str


def start_point(model: SPDModel, X: np.ndarray) -> int:
    """Index of the row of ``X`` (n, d) with the highest predicted success probability
    (the product of the factors; first one on ties)."""
    return int(np.argmax(model.success_proba(np.asarray(X, dtype=float))))


def start_points(model: SPDModel, X: np.ndarray, settings: LearningSettings) -> list[int]:
    """Indices of the ``refine_starts`` rows of ``X`` (n, d) to refine from, best first: the
    highest predicted success (first one on ties), then the highest expected success under
    the refinement's errors (:func:`~rgmcad.learning.errors.design_from_settings`)."""
    X = np.asarray(X, dtype=float)
    first = start_point(model, X)
    if settings.refine_starts == 1 or len(X) == 1:
        return [first]
    design = design_from_settings(X.shape[1], settings, settings.placement_samples,
                                  settings.placement_noise)
    rated = np.argsort(-expected_success(model, X, design), kind="stable")
    return [first] + [int(i) for i in rated if i != first][: settings.refine_starts - 1]


def maximize_robustness(
    model: SPDModel,
    penetration: PenetrationFn,
    x0: np.ndarray,
    settings: LearningSettings,
    *,
    optimizer: str | None = None,
) -> OptimizationResult:
    """Maximise ``model.objective`` subject to ``penetration(x) <= 0`` and ``0 <= x <= 1``.

    Parameters
    ----------
    model : SPDModel
    penetration : callable
        ``penetration(x) -> float``, >= 0, 0 iff valid.
    x0 : (d,) float
        Start point, normally valid.
    settings : LearningSettings
        ``optimizer``, ``optimizer_max_eval``, ``optimizer_xtol``,
        ``optimizer_initial_step``, ``constraint_tolerance``, ``fd_step``,
        ``placement_noise``, ``placement_samples``.
    optimizer : {"cobyla", "auglag", "slsqp"}, optional
        Overrides ``settings.optimizer``.

    Returns
    -------
    OptimizationResult
    """
    s = settings
    method = optimizer or s.optimizer
    if method not in _ALGORITHMS:
        raise ValueError(f"unknown optimizer {method!r}; valid: {sorted(_ALGORITHMS)}")
    x0 = np.clip(np.asarray(x0, dtype=float).reshape(-1), 0.0, 1.0)
    d = len(x0)
    design = design_from_settings(d, s, s.placement_samples, s.placement_noise)
    pen_cache: dict[bytes, float] = {}
    best = {"x": None, "f": -np.inf}
    n_eval = 0

    def pen(x: np.ndarray) -> float:
        key = np.asarray(x, dtype=float).tobytes()
        if key not in pen_cache:
            pen_cache[key] = float(penetration(np.array(x, dtype=float)))
        return pen_cache[key]

    def objective(x, grad):
        nonlocal n_eval
        n_eval += 1
        if design is None:
            f, g = model.objective(x)
        elif design.within_cube:  # the errors of the ball that keep x in the cube
            offsets, raw = design.at(x)
            w = design.normalized(raw)
            keep = w > 0
            f, g = (model.objective(x, offsets[keep], w[keep]) if keep.any()
                    else model.objective(x))
        else:
            f, g = model.objective(x, design.offsets)
        if grad.size > 0:
            grad[:] = g
        if f > best["f"] and pen(x) <= 0.0:
            best["x"], best["f"] = np.array(x, dtype=float), f
        return f

    def constraint(x, grad):
        c = pen(x)
        if grad.size > 0:
            h = s.fd_step
            for j in range(d):
                xj = np.array(x, dtype=float)
                # step inwards at the upper bound so the probe stays in the box
                step = h if xj[j] + h <= 1.0 else -h
                xj[j] += step
                grad[j] = (pen(xj) - c) / step
        return c

    f0 = objective(x0, np.empty(0))
    if pen(x0) > 0:
        logger.warning("maximize_robustness: the start point is invalid (penetration %g)", pen(x0))

    opt = nlopt.opt(_ALGORITHMS[method], d)
    opt.set_lower_bounds(np.zeros(d))
    opt.set_upper_bounds(np.ones(d))
    opt.set_max_objective(objective)
    opt.add_inequality_constraint(constraint, s.constraint_tolerance)
    opt.set_maxeval(s.optimizer_max_eval)
    opt.set_xtol_abs(np.full(d, s.optimizer_xtol))
    if method == "cobyla":
        opt.set_initial_step(np.full(d, s.optimizer_initial_step))
    elif method == "auglag":
        local = nlopt.opt(nlopt.LD_LBFGS, d)
        local.set_xtol_abs(np.full(d, s.optimizer_xtol))
        local.set_maxeval(s.optimizer_max_eval)
        opt.set_local_optimizer(local)
    try:
        opt.optimize(x0.copy())
        status = _STATUS.get(opt.last_optimize_result(), str(opt.last_optimize_result()))
    except (nlopt.RoundoffLimited, nlopt.exception) as err:  # keep the best point so far
        status = f"{type(err).__name__}: {err}"
        logger.info("maximize_robustness: nlopt stopped with %s", status)

    if best["x"] is None:  # nothing valid was visited, not even x0
        best["x"], best["f"] = x0, f0
    return OptimizationResult(
        x=best["x"],
        objective=float(best["f"]),
        x_start=x0,
        objective_start=float(f0),
        n_evaluations=n_eval,
        n_penetration_calls=len(pen_cache),
        status=status,
    )


_STATUS = {
    nlopt.SUCCESS: "success",
    nlopt.STOPVAL_REACHED: "stopval reached",
    nlopt.FTOL_REACHED: "ftol reached",
    nlopt.XTOL_REACHED: "xtol reached",
    nlopt.MAXEVAL_REACHED: "maxeval reached",
    nlopt.MAXTIME_REACHED: "maxtime reached",
}


def place_unmodelled(model: SPDModel, x: np.ndarray, successes: np.ndarray,
                     penetration: PenetrationFn) -> np.ndarray:
    """``x`` (d,) with each coordinate that no event's model depends on moved to the median
    of ``successes`` (k, d) along it, one coordinate at a time, each move kept only if the
    layout stays valid (``penetration`` 0). The refinement cannot move such a coordinate and
    leaves it where its start sample had it, which can be where the chain barely works
    (``LearningSettings.unmodelled_at``)."""
    x = np.asarray(x, dtype=float).copy()
    used = {j for e in model.learned_events for j in model.models[e].dims_}
    for j in sorted(set(range(len(x))) - used) if len(successes) else []:
        moved = x.copy()
        moved[j] = float(np.median(successes[:, j]))
        if penetration(moved) <= 0.0:
            x = moved
    return x


def placement_tolerance(
    model: SPDModel, x: np.ndarray, settings: LearningSettings,
    validity: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """How far each coordinate of ``x`` may move, alone, before the predicted success
    probability drops below ``tolerance_ratio`` times its value at ``x``, or (with
    ``validity``) before the layout stops being buildable (parts overlap).

    Along each axis and direction, the probability is scanned every ``tolerance_step`` up to
    the bound of the unit cube; the first crossing is refined by ``tolerance_bisections``
    bisection steps. Without a crossing the tolerance is the distance to the bound. The
    model has never seen an invalid layout (they are not simulated), so it can rate one
    highly: without the validity test a tolerance could run through another part.

    Parameters
    ----------
    model : SPDModel
    x : (d,) float
    settings : LearningSettings
    validity : ``(n, d) -> (n,) bool``, optional
        The exact validity test of design vectors (a problem's ``validity``).

    Returns
    -------
    (d, 2) float
        ``[[minus_0, plus_0], ...]`` in normalised units (>= 0); multiply by the range
        ``b - a`` of each parameter for real units.
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    d = len(x)
    threshold = settings.tolerance_ratio * float(model.success_proba(x)[0])

    def fails(P: np.ndarray) -> np.ndarray:
        out = model.success_proba(P) < threshold
        return out if validity is None else out | ~np.asarray(validity(P), dtype=bool)

    out = np.zeros((d, 2))
    for j in range(d):
        for k, sign in enumerate((-1.0, 1.0)):
            room = x[j] if sign < 0 else 1.0 - x[j]
            if room <= 0:
                continue
            n_steps = int(np.ceil(room / settings.tolerance_step))
            t = np.minimum(np.arange(1, n_steps + 1) * settings.tolerance_step, room)
            P = np.repeat(x[None, :], len(t), axis=0)
            P[:, j] += sign * t
            below = np.flatnonzero(fails(P))
            if below.size == 0:
                out[j, k] = room
                continue
            hi = t[below[0]]
            lo = t[below[0] - 1] if below[0] > 0 else 0.0
            for _ in range(settings.tolerance_bisections):
                mid = 0.5 * (lo + hi)
                p = x.copy()
                p[j] += sign * mid
                if fails(p[None, :])[0]:
                    hi = mid
                else:
                    lo = mid
            out[j, k] = lo
    return out


def overlap_ends(x: np.ndarray, tolerances: np.ndarray, settings: LearningSettings,
                 validity: Callable[[np.ndarray], np.ndarray]) -> list[str | None]:
    """Per coordinate of ``x``, the sides (``"low"``, ``"high"``, ``"both"`` or None) whose
    ``tolerances`` (as :func:`placement_tolerance` gives them with ``validity``) stop where
    parts would overlap: the layout just past the tolerance is invalid."""
    x = np.asarray(x, dtype=float).reshape(-1)
    past = 2.0 * settings.tolerance_step / 2 ** settings.tolerance_bisections
    probes, where = [], []
    for j in range(len(x)):
        for k, sign in enumerate((-1.0, 1.0)):
            v = x[j] + sign * (tolerances[j, k] + past)
            if 0.0 <= v <= 1.0:
                p = x.copy()
                p[j] = v
                probes.append(p)
                where.append((j, k))
    hit = np.zeros((len(x), 2), dtype=bool)
    if probes:
        for (j, k), ok in zip(where, validity(np.array(probes)), strict=True):
            hit[j, k] = not ok
    return ["both" if lo and hi else "low" if lo else "high" if hi else None
            for lo, hi in hit]


def range_ends(x: np.ndarray, tolerances: np.ndarray) -> list[str | None]:
    """Per coordinate of ``x``, the ends of the unit cube its ``tolerances`` (as
    :func:`placement_tolerance` gives them) reach: ``"low"``, ``"high"``, ``"both"`` or None.
    A tolerance that reaches an end is the range's, not the layout's: nothing beyond a range
    is simulated, so the model cannot say where the layout would fail past it."""
    x = np.asarray(x, dtype=float).reshape(-1)
    low = x - tolerances[:, 0] <= 1e-9
    high = x + tolerances[:, 1] >= 1.0 - 1e-9
    return ["both" if lo and hi else "low" if lo else "high" if hi else None
            for lo, hi in zip(low, high, strict=True)]

