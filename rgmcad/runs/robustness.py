"""How robust is a layout? Local robustness ``rho_l(x, eps)`` by Monte Carlo and global
robustness ``rho_g`` (paper section 8, Fig. 15; SPEC section 5.6).

``rho_l(x, eps)`` is the success rate of valid layouts drawn uniformly in the Euclidean ball
of radius ``eps + eta`` around ``x`` in the normalised design space ``[0, 1]^d``; ``rho_g`` is
its trapezoid integral over ``eps``.

How the numbers compare with the paper's
----------------------------------------
* **Normalisation**: the same as the authors' (SPEC 3.2): each free parameter mapped
  linearly from its range to [0, 1], so a distance of 0.1 is 10 % of every range at once.
  Numbers compare where the scenario's ranges are the authors' (each scenario file records
  any departure).
* **Grid**: ``eps`` in ``linspace(0, 1, 30)`` and balls of radius ``eps + eta`` with
  ``eta = 1/300``, as in the authors' ``compute_local_rob_curve``; ``rho_g`` is
  ``trapz(rho_l, eps)`` over that grid, as theirs. Only ``eps`` <= 1 is covered although
  distances in the cube reach ``sqrt(d)``: theirs too.
* **Estimator**: the authors filtered one dense Sobol set (1M points; 100K for
  CAUSALITYSWITCH) by distance to ``x``, plus 100 points in the L-infinity cube ``x +- eta``.
  Both estimate the same quantity, the success fraction of valid layouts uniform in the ball
  intersected with the cube, but a dense set puts almost no points in small balls of a
  high-dimensional space (a ball of radius 0.1 holds a fraction 4e-8 of the 8-D cube), so
  their small-``eps`` values rest on the 100 local points. Here every radius gets its own
  ``n`` valid samples drawn uniformly in the ball: points outside ``[0, 1]^d`` are
  **rejected**, not clipped (clipping would pile them onto the faces of the cube, which a
  dense set of the cube never does), and invalid layouts are dropped, as the authors did.
  Each value has a Wilson 95 % interval; ``rho_g``'s interval is the normal approximation
  of the weighted sum of independent estimates.
* **Invalid x**: like the authors' code, ``rho_l`` is not forced to 0 when ``x`` itself is
  invalid; the neighbours are counted. A ball with no valid layout at all gives 0.
* The paper averages 10 runs of each method; a single ``evaluate`` scores one layout.

Physical uncertainty
--------------------
The paper perturbs positions only. Given ``physics`` (:class:`~rgmcad.scene.perturbation.
PhysicsRanges`), every chosen layout is simulated a second time with its own draw of
friction, masses and restitution, and the curve carries a second curve, ``physics``: the
success rate under placement *and* physical errors, on the very same layouts (a paired
comparison). Draw ``k * n + j`` goes to the ``j``-th layout of the ``k``-th radius, under a
seed derived from ``rng``: the same seed gives every evaluated layout, of any method, the same
physical draws (common random numbers).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from rgmcad.files import naming
from rgmcad.geometry import dot
from rgmcad.runs.problem import SimRecord, simulate_layout_task
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges
from rgmcad.sim.run import Outcome

__all__ = ["ETA", "EPS_GRID", "CLOSE_IN", "RobustnessCurve", "ball_samples", "wilson_interval",
           "local_robustness", "robustness_on", "figures", "failure_counts", "first_failure",
           "failures_line", "plot_curves", "trapezoid_weights", "close_in_warning", "two_rates"]

ETA = 1.0 / 300.0
"""Offset added to every radius (the authors' ``1 / (10 N_STEPS)``)."""

EPS_GRID = np.linspace(0.0, 1.0, 30)
"""The authors' radii."""

CLOSE_IN = 0.1
"""Radius of the layouts whose failures tell a builder where to take care (10 % of every
range): further out, failures say more about the design space than about the build."""


@dataclass(frozen=True)
class RobustnessCurve:
    """Result of :func:`local_robustness`.

    Attributes
    ----------
    x : (d,) float
        The layout, normalised.
    eps : (k,) float
        Radii (the ball radius is ``eps + eta``).
    successes, counts : (k,) int
        Successful and valid simulated layouts per radius.
    rho : (k,) float
        Success fraction per radius (0 where no valid layout was found).
    low, high : (k,) float
        Wilson interval per radius.
    rho_g : float
        ``trapz(rho, eps)``.
    rho_g_low, rho_g_high : float
        Its approximate interval (same confidence).
    simulations : int
        Simulations run (valid layouts).
    validity_tests : int
        Candidates tested for validity.
    eta : float
    physics : RobustnessCurve or None
        The same layouts' curve under placement and physical errors, when asked for.
    failed_at : tuple of str or None
        Per simulated layout, radius by radius: the event it failed at first
        (:func:`first_failure`), None for a success.
    """

    x: np.ndarray
    eps: np.ndarray
    successes: np.ndarray
    counts: np.ndarray
    rho: np.ndarray
    low: np.ndarray
    high: np.ndarray
    rho_g: float
    rho_g_low: float
    rho_g_high: float
    simulations: int
    validity_tests: int
    eta: float = ETA
    physics: RobustnessCurve | None = None
    failed_at: tuple[str | None, ...] = ()

    def curve(self) -> list[list[float]]:
        """``[[eps, rho_l, low, high], ...]``."""
        return [[float(e), float(r), float(lo), float(hi)]
                for e, r, lo, hi in zip(self.eps, self.rho, self.low, self.high, strict=True)]


def wilson_interval(successes, counts, z: float = 1.959964) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval of binomial proportions (elementwise; (0, 1) when count is 0)."""
    k = np.asarray(successes, dtype=float)
    n = np.asarray(counts, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = np.where(n > 0, k / n, 0.0)
        denom = 1 + z * z / n
        centre = (p + z * z / (2 * n)) / denom
        half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = np.where(n > 0, np.clip(centre - half, 0, 1), 0.0)
    high = np.where(n > 0, np.clip(centre + half, 0, 1), 1.0)
    return low, high


def ball_samples(x: np.ndarray, radius: float, n: int, rng: np.random.Generator,
                 max_draws: int = 1_000_000) -> np.ndarray:
    """Up to ``n`` points uniform in the L2 ball ``|y - x| <= radius`` intersected with
    ``[0, 1]^d`` (rejection of the points outside the cube), at most ``max_draws`` drawn.

    Returns
    -------
    (m, d) float, m <= n
    """
    x = np.asarray(x, dtype=float)
    d = len(x)
    out, drawn, kept = [], 0, 0
    while kept < n and drawn < max_draws:
        m = min(max_draws - drawn, max(4 * (n - kept), 1024))
        u = rng.standard_normal((m, d))
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        r = radius * rng.random(m) ** (1.0 / d)
        Y = x + u * r[:, None]
        Y = Y[np.all((Y >= 0) & (Y <= 1), axis=1)][: n - kept]
        out.append(Y)
        kept += len(Y)
        drawn += m
    return np.vstack(out) if out else np.empty((0, d))


def local_robustness(
    x: np.ndarray,
    validity: Callable[[np.ndarray], np.ndarray],
    simulate: Callable[[np.ndarray], list[SimRecord]],
    n: int,
    rng: np.random.Generator | int | None = None,
    *,
    eps: np.ndarray = EPS_GRID,
    eta: float = ETA,
    candidate_factor: int = 100,
    z: float = 1.959964,
    on_progress: Callable[[str, int], None] | None = None,
    physics: PhysicsRanges | None = None,
) -> RobustnessCurve:
    """Estimate ``rho_l(x, eps)`` on a grid of radii and ``rho_g`` (see the module docstring).

    For each radius, candidates uniform in the ball (inside the cube) are tested for validity
    in order until ``n`` are valid (at most ``candidate_factor * n`` candidates); all chosen
    layouts of all radii are then simulated together. Each radius draws from its own
    generator (spawned from ``rng``), so the result does not depend on how the work is spread.

    Parameters
    ----------
    x : (d,) float
        The layout (normalised).
    validity : callable
        ``validity(X) -> (m,) bool``.
    simulate : callable
        ``simulate(X) -> list[SimRecord]``; with ``physics``, also called as
        ``simulate(X, draws)`` with one :class:`~rgmcad.scene.perturbation.PhysicsDraw` per row.
    n : int
        Valid layouts simulated per radius.
    rng : numpy.random.Generator or int, optional
    eps : (k,) float
        Radii, default :data:`EPS_GRID`.
    eta : float
        Added to every radius.
    on_progress : callable, optional
        ``on_progress(stage, count)`` after each validity block and after simulating.
    physics : PhysicsRanges, optional
        Also estimate the curve under physical errors (the result's ``physics``).

    Returns
    -------
    RobustnessCurve
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    eps = np.asarray(eps, dtype=float)
    root = int(np.random.default_rng(rng).integers(2**63))
    gens = [np.random.default_rng(s) for s in np.random.SeedSequence(root).spawn(len(eps))]
    chosen: list[np.ndarray] = []
    n_tested = 0
    for k, e in enumerate(eps):
        cands = ball_samples(x, e + eta, candidate_factor * n, gens[k])
        kept: list[np.ndarray] = []
        n_kept, start = 0, 0
        while n_kept < n and start < len(cands):
            block = cands[start:start + 2 * (n - n_kept)]
            ok = np.asarray(validity(block), dtype=bool)
            kept.append(block[ok][: n - n_kept])
            n_kept += len(kept[-1])
            start += len(block)
        n_tested += start
        chosen.append(np.vstack(kept) if kept else np.empty((0, len(x))))
        if on_progress is not None:
            on_progress("validity", n_tested)
    sizes = [len(c) for c in chosen]
    X = np.vstack(chosen)
    records = simulate(X) if len(X) else []
    if on_progress is not None:
        on_progress("simulated", len(records))
    physical = None
    if physics is not None:
        draws = [PhysicsDraw(physics, root, k * n + j)
                 for k, size in enumerate(sizes) for j in range(size)]
        perturbed = simulate(X, draws) if len(X) else []
        if on_progress is not None:
            on_progress("simulated", len(perturbed))
        physical = _curve(x, eps, sizes, perturbed, n_tested, z, eta)
    return dataclasses.replace(_curve(x, eps, sizes, records, n_tested, z, eta),
                               physics=physical)


def robustness_on(executor, x, validity, samples: int, seed, physics=None,
                  progress=None) -> RobustnessCurve:
    """:func:`local_robustness` of ``x`` with the simulations spread over ``executor`` (its
    context a :class:`~rgmcad.runs.problem.ScenarioContext`); ``progress``: a
    :class:`~rgmcad.runs.workflow.RunProgress` told of each stage and simulation."""
    def simulate(X, draws=None):
        if progress is not None:
            progress.stage("simulation" if draws is None else "simulation + physics", len(X))
        draws = [None] * len(X) if draws is None else draws
        out = []
        # local_robustness simulates only layouts that validity() passed: not tested again
        items = [(v, True, d) for v, d in zip(X, draws, strict=True)]
        for r in executor.map_context(simulate_layout_task, items):
            out.append(r)
            if progress is not None:
                progress.simulated(r)
        return out

    return local_robustness(x, validity, simulate, samples, seed, physics=physics)


def figures(curve: RobustnessCurve, physics: PhysicsRanges | None = None) -> dict:
    """A curve as JSON: rho_g, its interval, the curve ``[[eps, rho_l, low, high], ...]``,
    counts, simulations and where layouts failed (:func:`failure_counts`), and the same under
    ``physics`` (None when not estimated)."""
    out = {"rho_g": curve.rho_g, "rho_g_interval": [curve.rho_g_low, curve.rho_g_high],
           "curve": curve.curve(), "counts": [int(c) for c in curve.counts],
           "simulations": curve.simulations, "failures": failure_counts(curve),
           "physics": None}
    p = curve.physics
    if p is not None:
        out["physics"] = {"ranges": None if physics is None else physics.to_json(),
                          "rho_g": p.rho_g, "rho_g_interval": [p.rho_g_low, p.rho_g_high],
                          "curve": p.curve(), "simulations": p.simulations,
                          "failures": failure_counts(p)}
    return out


def two_rates(a: float, b: float) -> tuple[str, str]:
    """Two success rates written with two decimals, or with as many more (up to five) as it
    takes to show which is higher: a report that says "0.29 against 0.29, so the second was
    kept" reads as a mistake when the rates were 0.293 and 0.296."""
    digits = 2
    while digits < 5 and a != b and f"{a:.{digits}f}" == f"{b:.{digits}f}":
        digits += 1
    return f"{a:.{digits}f}", f"{b:.{digits}f}"


def close_in_warning(figure: dict | None, point_to_evaluate: bool = False) -> str | None:
    """When the layouts closest to the one measured (its first radius, ``ETA``) did not all
    succeed in :func:`figures`' output: a sentence saying so (and that ``rgmcad evaluate``
    measures it better, with ``point_to_evaluate``), else None. rho_g gives that radius one
    thirtieth of its weight, so a layout can score well and still fail where it is placed
    exactly (a chain balanced on a knife edge)."""
    if not figure or not figure.get("curve") or not figure.get("counts"):
        return None
    n = int(figure["counts"][0])
    wins = round(figure["curve"][0][1] * n)
    if n == 0 or wins == n:
        return None
    return (f"only {wins} of the {n} layouts within 1/300 of this one succeeded: it may fail "
            "even when placed exactly"
            + (" (`rgmcad evaluate` measures it with more layouts)" if point_to_evaluate else ""))


def _curve(x, eps, sizes, records, n_tested, z, eta) -> RobustnessCurve:
    success = np.array([r.outcome is Outcome.SUCCESS for r in records], dtype=bool)
    bounds = np.cumsum([0, *sizes])
    succ = np.array([success[bounds[k]:bounds[k + 1]].sum() for k in range(len(eps))])
    counts = np.asarray(sizes)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.where(counts > 0, succ / np.maximum(counts, 1), 0.0)
    low, high = wilson_interval(succ, counts, z)
    weights = trapezoid_weights(eps)
    rho_g = float(dot(weights, rho))  # the same last bit on every CPU (no BLAS)
    var = np.where(counts > 0, rho * (1 - rho) / np.maximum(counts, 1), 0.25)
    half = z * float(np.sqrt(dot(weights**2, var)))
    return RobustnessCurve(
        x=x, eps=eps, successes=succ, counts=counts, rho=rho, low=low, high=high,
        rho_g=rho_g, rho_g_low=max(0.0, rho_g - half), rho_g_high=min(1.0, rho_g + half),
        simulations=len(records), validity_tests=int(n_tested), eta=eta,
        failed_at=tuple(first_failure(r) for r in records),
    )


def first_failure(record: SimRecord) -> str | None:
    """The event a failed simulation failed at first: the earliest event labelled a failure,
    else (the run ended with events pending) the first never resolved in the scenario's order;
    None for a success or an invalid layout."""
    if record.outcome is not Outcome.FAILURE:
        return None
    failed = [(t, name) for name, (label, t) in record.events.items()
              if label is False and t is not None]
    if failed:
        return min(failed)[1]
    return next((name for name, (label, _) in record.events.items() if label is None), None)


def failure_counts(curve: RobustnessCurve, within: float = CLOSE_IN) -> dict:
    """Where the curve's layouts within radius ``within`` (eps <= within) and all of them
    failed first: ``{"close_in": {"radius", "layouts", "failed": {event: count}}, "all":
    {...}}``, events most frequent first."""
    close = int(np.sum(np.asarray(curve.counts)[np.asarray(curve.eps) <= within + 1e-12]))
    out = {}
    for key, names in (("close_in", curve.failed_at[:close]), ("all", curve.failed_at)):
        counts: dict[str, int] = {}
        for name in names:
            if name is not None:
                counts[name] = counts.get(name, 0) + 1
        out[key] = {"layouts": len(names),
                    "failed": dict(sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))}
    out["close_in"]["radius"] = within
    return out


def failures_line(close_in: dict, most: int = 3) -> str | None:
    """Where the layouts nearest the evaluated one failed first, the ``most`` commonest
    events (None when all succeeded)."""
    failed = close_in["failed"]
    if not failed:
        return None
    n = close_in["layouts"]
    shown = ", ".join(f"{name} {count}" for name, count in list(failed.items())[:most])
    more = len(failed) - most
    return (f"first failures within radius {close_in['radius']:g} ({sum(failed.values())} of "
            f"{n} layouts): {shown}" + (f" and {more} more" if more > 0 else ""))


def trapezoid_weights(t: np.ndarray) -> np.ndarray:
    """w with ``w @ f == trapz(f, t)``."""
    w = np.zeros(len(t))
    dt = np.diff(t)
    w[:-1] += dt / 2
    w[1:] += dt / 2
    return w


def plot_curves(curves: dict[str, RobustnessCurve], path, title: str = "") -> None:
    """Local robustness against eps with the confidence band, one line per layout, like the
    paper's Fig. 15 (matplotlib, Agg); a curve's ``physics`` curve dashed in its colour."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    for name, c in curves.items():
        (line,) = ax.plot(c.eps, c.rho, label=f"{name}, placement (rho_g = {c.rho_g:.3f})"
                          if c.physics is not None else f"{name} (rho_g = {c.rho_g:.3f})")
        ax.fill_between(c.eps, c.low, c.high, color=line.get_color(), alpha=0.2, lw=0)
        if c.physics is not None:  # same colour, dashed, its band hatched
            p = c.physics
            ax.plot(p.eps, p.rho, ls="--", color=line.get_color(),
                    label=f"{name}, placement + physics (rho_g = {p.rho_g:.3f})")
            ax.fill_between(p.eps, p.low, p.high, color=line.get_color(), alpha=0.1, lw=0)
    ax.set_xlabel("eps (radius in the normalised design space)")
    ax.set_ylabel("local robustness rho_l")
    ax.set_xlim(0, float(max(c.eps.max() for c in curves.values())))
    ax.set_ylim(0, 1.02)
    save_plot(fig, ax, path, title, "upper right")


def save_plot(fig, ax, path, title: str = "", legend: str = "best") -> None:
    """Grid, legend at ``legend``, ``title``: the plot written to ``path`` and closed."""
    import matplotlib.pyplot as plt

    ax.grid(alpha=0.3)
    ax.legend(loc=legend, fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def save_figure(fig, path) -> None:
    """``fig.savefig(path)``; a write that fails (a full disk) names ``path``."""
    with naming(path):
        fig.savefig(path)
