"""The searches the paper compares its method with (section 8.3, Table 1), and CMA-ES.

Each is a function over a :class:`~rgmcad.learning.oracles.Problem` with the same signature,
``method(problem, budget, rng) -> BaselineResult``: at most ``budget`` simulations (validity
tests are not counted; a ``budget`` the method cannot split exactly is left partly unused, and
:attr:`BaselineResult.n_simulations` says how much was used), one layout returned.

* :func:`random_search` (B1): valid uniform layouts, simulated in draw order until one succeeds.
* :func:`uniform_search` (B2): valid uniform layouts scored by a local robustness estimate
  (:func:`local_estimate`); the best-scored one.
* :func:`gp_search` (B3): Gaussian-process optimisation of the same estimate (Matern 5/2
  kernel, expected improvement); the best-scored layout observed.
* :func:`cmaes_search`: CMA-ES (the ``cma`` package) on the same estimate; the best-scored
  layout observed.

The estimate, as the authors' ``LocalRobustnessEstimator``: the success fraction of the layout
itself plus ``n_local = d^2`` valid layouts uniform in the L-infinity cube of half-width 0.1
around it, so one score costs ``d^2 + 1`` simulations and a budget ``B`` buys
``n_eval = B // (d^2 + 1)`` scores. Where this differs from the authors' code, see
docs/decisions.md ("Baselines").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .oracles import Problem

__all__ = ["BaselineResult", "BudgetExceeded", "BASELINES", "local_estimate", "random_search",
           "uniform_search", "gp_search", "cmaes_search"]

RADIUS = 0.1
"""Half-width of the cube of :func:`local_estimate` (the authors' ``radius``)."""

DRAWS_PER_SAMPLE = 100
"""Most uniform draws per valid layout wanted (the authors' ``100 n``)."""


class BudgetExceeded(RuntimeError):
    """A method asked for more simulations than its budget (a bug: never raised by design)."""


@dataclass(frozen=True)
class BaselineResult:
    """What a baseline returns.

    Attributes
    ----------
    x : (d,) float
        The layout found, in ``[0, 1]^d``.
    method : str
    score : float
        The method's own view of ``x``: 1.0/0.0 for B1 (success of its simulation), the local
        robustness estimate for the others.
    budget : int
    n_simulations : int
        Simulations used (<= budget).
    n_validity_tests : int
        Layouts tested for validity (not counted in the budget).
    n_evaluations : int
        Scores computed (B1: layouts simulated).
    wall_time : float
        Seconds the call took.
    history : (n, d + 1) float
        Every scored layout and its score, in order.
    """

    x: np.ndarray
    method: str
    score: float
    budget: int
    n_simulations: int
    n_validity_tests: int
    n_evaluations: int
    wall_time: float
    history: np.ndarray = field(repr=False)


class _Counted:
    """The problem's validity and simulator, counted; the budget is enforced here."""

    def __init__(self, problem: Problem, budget: int):
        if isinstance(budget, bool) or not isinstance(budget, (int, np.integer)) or budget < 1:
            raise ValueError(f"budget: expected a positive number of simulations, got {budget!r}")
        self.problem, self.budget = problem, int(budget)
        self.d = int(problem.dimension)
        self.n_sim = self.n_valid_tests = 0

    @property
    def left(self) -> int:
        return self.budget - self.n_sim

    def validity(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(X)
        self.n_valid_tests += len(X)
        return np.asarray(self.problem.validity(X), dtype=bool).reshape(-1)

    def success(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(X)
        if len(X) > self.left:
            raise BudgetExceeded(f"{len(X)} simulations asked, {self.left} left of {self.budget}")
        self.n_sim += len(X)
        labels = self.problem.simulate(X)
        return np.array([bool(lab.success) for lab in labels], dtype=bool)

    def valid_uniform(self, n: int, rng: np.random.Generator, lo=None, hi=None) -> np.ndarray:
        """Up to ``n`` valid layouts uniform in the box ``[lo, hi]`` (default the unit cube),
        from at most ``DRAWS_PER_SAMPLE * n`` draws, in draw order."""
        lo = np.zeros(self.d) if lo is None else lo
        hi = np.ones(self.d) if hi is None else hi
        out, drawn = [], 0
        while sum(map(len, out)) < n and drawn < DRAWS_PER_SAMPLE * n:
            m = min(DRAWS_PER_SAMPLE * n - drawn, max(2 * (n - sum(map(len, out))), 16))
            Y = lo + (hi - lo) * rng.random((m, self.d))
            drawn += m
            out.append(Y[self.validity(Y)])
        Y = np.vstack(out) if out else np.empty((0, self.d))
        return Y[:n]

    def result(self, method, x, score, n_eval, start, history) -> BaselineResult:
        hist = np.array([[*h[0], h[1]] for h in history]) if history else np.empty((0, self.d + 1))
        return BaselineResult(np.asarray(x, dtype=float).copy(), method, float(score),
                              self.budget, self.n_sim, self.n_valid_tests, int(n_eval),
                              time.perf_counter() - start, hist)


def _rng(rng) -> np.random.Generator:
    return np.random.default_rng(rng)


def local_estimate(x: np.ndarray, problem: Problem, n_local: int, rng, *,
                   radius: float = RADIUS, counted: _Counted | None = None) -> float | None:
    """Success fraction of ``x`` and ``n_local`` valid layouts uniform in the cube
    ``x +- radius`` intersected with ``[0, 1]^d``; None (no simulation) when ``x`` is
    invalid. At most ``n_local + 1`` simulations."""
    c = counted or _Counted(problem, n_local + 1)
    x = np.asarray(x, dtype=float).reshape(-1)
    if not c.validity(x[None, :])[0]:
        return None
    gen = _rng(rng)
    near = c.valid_uniform(n_local, gen, np.maximum(x - radius, 0), np.minimum(x + radius, 1))
    return float(c.success(np.vstack([x[None, :], near])).mean())


def _n_local(d: int, budget: int) -> tuple[int, int]:
    """(n_local, n_eval): ``d^2`` local layouts, ``budget // (d^2 + 1)`` scores; a budget
    too small for one full score gets one score of ``budget - 1`` local layouts."""
    n_local = d * d
    if budget < n_local + 1:
        return budget - 1, 1
    return n_local, budget // (n_local + 1)


# --- B1 ----------------------------------------------------------------------------------------


def random_search(problem: Problem, budget: int, rng=None, *, batch: int = 8) -> BaselineResult:
    """B1: valid uniform layouts simulated in draw order, ``batch`` at a time (for a parallel
    simulator), until one succeeds; the first success in draw order, else the last layout
    simulated. The layout returned does not depend on ``batch``; the simulations used do
    (at most ``batch - 1`` after the success)."""
    start = time.perf_counter()
    c, gen = _Counted(problem, budget), _rng(rng)
    history, x_last = [], None
    queue, drawn = np.empty((0, c.d)), 0  # valid layouts in draw order, drawn 64 at a time
    while c.left > 0:
        while len(queue) < min(batch, c.left) and drawn < DRAWS_PER_SAMPLE * c.budget:
            Y = gen.random((64, c.d))
            drawn += 64
            queue = np.vstack([queue, Y[c.validity(Y)]])
        X, queue = queue[:min(batch, c.left)], queue[min(batch, c.left):]
        if len(X) == 0:
            break
        ok = c.success(X)
        history += [(x, float(s)) for x, s in zip(X, ok, strict=True)]
        x_last = X[-1]
        if ok.any():
            i = int(np.argmax(ok))
            return c.result("b1", X[i], 1.0, len(history), start, history)
    if x_last is None:
        raise RuntimeError("random search found no valid layout")
    return c.result("b1", x_last, 0.0, len(history), start, history)


# --- B2 ----------------------------------------------------------------------------------------


def uniform_search(problem: Problem, budget: int, rng=None, *,
                   radius: float = RADIUS) -> BaselineResult:
    """B2: ``n_eval`` valid uniform layouts, each scored by :func:`local_estimate`; the
    best-scored (the first of equals)."""
    start = time.perf_counter()
    c, gen = _Counted(problem, budget), _rng(rng)
    n_local, n_eval = _n_local(c.d, c.budget)
    X = c.valid_uniform(n_eval, gen)
    if len(X) == 0:
        raise RuntimeError("uniform search found no valid layout")
    history = [(x, local_estimate(x, problem, n_local, gen, radius=radius, counted=c))
               for x in X]
    i = int(np.argmax([s for _, s in history]))
    return c.result("b2", X[i], history[i][1], len(history), start, history)


# --- B3 ----------------------------------------------------------------------------------------


def _expected_improvement(gp, X: np.ndarray, best: float, xi: float) -> np.ndarray:
    from scipy.stats import norm

    mu, sd = gp.predict(np.atleast_2d(X), return_std=True)
    sd = np.maximum(sd, 1e-12)
    z = (mu - best - xi) / sd
    return (mu - best - xi) * norm.cdf(z) + sd * norm.pdf(z)


def _maximize_ei(gp, d: int, best: float, xi: float, gen, n_warmup: int, n_starts: int):
    from scipy.optimize import minimize

    W = gen.random((n_warmup, d))
    ei = _expected_improvement(gp, W, best, xi)
    order = np.argsort(-ei, kind="stable")[:n_starts]
    x_best, v_best = W[order[0]], ei[order[0]]
    for x0 in W[order]:
        r = minimize(lambda z: -_expected_improvement(gp, z, best, xi)[0], x0,
                     method="L-BFGS-B", bounds=[(0.0, 1.0)] * d)
        if r.success and -r.fun > v_best:
            x_best, v_best = np.clip(r.x, 0, 1), -r.fun
    return x_best


def gp_search(problem: Problem, budget: int, rng=None, *, radius: float = RADIUS,
              xi: float = 0.0, n_restarts: int = 25, n_warmup: int = 100_000,
              n_starts: int = 10) -> BaselineResult:
    """B3: Gaussian-process optimisation of :func:`local_estimate` (scikit-learn's
    ``GaussianProcessRegressor``, Matern 5/2, ``alpha = 1e-6``, normalised targets,
    ``n_restarts`` fits of the kernel). ``n_eval // 2`` valid uniform layouts first, then
    the layouts of highest expected improvement (``xi``): the best of ``n_warmup`` uniform
    points refined by L-BFGS-B from the ``n_starts`` best of them. An invalid proposal is
    recorded with score 0 and costs no score (at most ``10 n_eval`` of them, then a valid
    uniform layout is scored instead). Returns the best-scored layout observed."""
    import warnings

    from sklearn.exceptions import ConvergenceWarning
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import Matern

    start = time.perf_counter()
    c, gen = _Counted(problem, budget), _rng(rng)
    n_local, n_eval = _n_local(c.d, c.budget)
    n_init = max(1, n_eval // 2)
    history = [(x, local_estimate(x, problem, n_local, gen, radius=radius, counted=c))
               for x in c.valid_uniform(n_init, gen)]
    if not history:
        raise RuntimeError("GP search found no valid layout")
    observed = list(history)  # with the invalid proposals at 0, for the GP
    n_invalid = 0
    while len(history) < n_eval:
        gp = GaussianProcessRegressor(kernel=Matern(nu=2.5), alpha=1e-6, normalize_y=True,
                                      n_restarts_optimizer=n_restarts,
                                      random_state=int(gen.integers(2**31)))
        with warnings.catch_warnings():  # a length scale at its bound: flat scores so far
            warnings.simplefilter("ignore", ConvergenceWarning)
            gp.fit(np.array([x for x, _ in observed]), np.array([s for _, s in observed]))
        best = max(s for _, s in observed)
        x = _maximize_ei(gp, c.d, best, xi, gen, n_warmup, n_starts)
        s = local_estimate(x, problem, n_local, gen, radius=radius, counted=c)
        if s is None:
            n_invalid += 1
            observed.append((x, 0.0))
            if n_invalid <= 10 * n_eval:
                continue
            x = c.valid_uniform(1, gen)[0]
            s = local_estimate(x, problem, n_local, gen, radius=radius, counted=c)
        history.append((x, s))
        observed.append((x, s))
    i = int(np.argmax([s for _, s in history]))
    return c.result("b3", history[i][0], history[i][1], len(history), start, history)


# --- CMA-ES ------------------------------------------------------------------------------------


def cmaes_search(problem: Problem, budget: int, rng=None, *, radius: float = RADIUS,
                 sigma0: float = 0.25, popsize: int | None = None) -> BaselineResult:
    """CMA-ES (``cma``, bounds ``[0, 1]^d`` by its BoundTransform) maximising
    :func:`local_estimate`, from a valid uniform layout with step ``sigma0``; its normal
    draws come from ``rng`` (the global numpy generator is left alone). An invalid candidate
    scores 0 and costs no score (at most ``10 n_eval`` of them). Stops when ``n_eval`` scores
    are spent (a generation cut short is not told); returns the best-scored layout observed."""
    import cma

    start = time.perf_counter()
    c, gen = _Counted(problem, budget), _rng(rng)
    n_local, n_eval = _n_local(c.d, c.budget)
    x0 = c.valid_uniform(1, gen)
    if len(x0) == 0:
        raise RuntimeError("CMA-ES found no valid layout to start from")
    opts = {"bounds": [0.0, 1.0], "seed": np.nan, "verbose": -9, "verb_log": 0,
            "verb_disp": 0, "randn": lambda *shape: gen.standard_normal(shape),
            "tolfun": 0, "tolflatfitness": 10**9, "tolx": 0, "tolstagnation": 10**9}
    if popsize is not None:
        opts["popsize"] = popsize
    es = cma.CMAEvolutionStrategy(x0[0].tolist(), sigma0, opts)
    history, n_invalid = [], 0
    while len(history) < n_eval:
        asked = es.ask()
        losses = []
        for candidate in asked:
            if len(history) >= n_eval:
                break
            x = np.clip(np.asarray(candidate, dtype=float), 0, 1)
            s = local_estimate(x, problem, n_local, gen, radius=radius, counted=c)
            if s is None:
                losses.append(0.0)
                n_invalid += 1
                if n_invalid <= 10 * n_eval:
                    continue
                x = c.valid_uniform(1, gen)[0]  # too many invalid candidates: score another
                s = local_estimate(x, problem, n_local, gen, radius=radius, counted=c)
            else:
                losses.append(-s)
            history.append((x, s))
        if len(losses) == len(asked):
            es.tell(asked, losses)
    i = int(np.argmax([s for _, s in history]))
    return c.result("cma", history[i][0], history[i][1], len(history), start, history)


BASELINES: dict[str, Callable[..., BaselineResult]] = {
    "b1": random_search, "b2": uniform_search, "b3": gp_search, "cma": cmaes_search}
"""Name -> function, in the order of the paper's Table 1 (CMA-ES last: not in the paper)."""
