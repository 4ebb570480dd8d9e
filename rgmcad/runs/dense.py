"""The authors' robustness protocol (SPEC 5.6): one dense Sobol set per scenario, reused for
every layout, plus a few local points per layout; measured against ours in
``tools/dense_protocol.py``.

``rho_l(x, eps)`` is the success fraction of the valid points at Euclidean distance at most
``eps + eta`` from ``x``, counting the dense set's points and ``x``'s local points (uniform
in the L-infinity cube ``x +- eta``) together; ``rho_g`` is its trapezoid integral over the
same grid as :mod:`rgmcad.runs.robustness`. Two departures from the authors' code, both so
that the estimate targets the same quantity as ours: the dense set is a *scrambled* Sobol
sequence (an unbiased estimate; the authors used Burkardt's unscrambled tables), and local
points are drawn in the cube intersected with ``[0, 1]^d`` (ours rejects points outside the
design space; the authors' were not clipped).

A dense set puts few points in a small ball: in 8-D, a ball of radius 0.1 holds 4e-8 of the
cube, so ``N = 2^14`` points leave it empty and ``rho_l`` for small ``eps`` is the success
rate of the local points alone, all within ``eta sqrt(d)`` of ``x``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.stats import qmc

from rgmcad.geometry import dot
from rgmcad.runs.robustness import (
    EPS_GRID,
    ETA,
    RobustnessCurve,
    trapezoid_weights,
    wilson_interval,
)
from rgmcad.sim.run import Outcome

__all__ = ["dense_valid_set", "simulated_outcomes", "local_points", "dense_curve", "balls_of"]


def dense_valid_set(validity: Callable[[np.ndarray], np.ndarray], dimension: int, n: int,
                    seed: int, block: int = 4096, max_candidates: int = 1 << 26) -> np.ndarray:
    """The first ``n`` valid points of one scrambled Sobol sequence in ``[0, 1]^d``, in order
    (so the first ``m < n`` are what ``n = m`` gives: one set serves every smaller size).

    Parameters
    ----------
    validity : callable
        ``validity(X) -> (m,) bool``.
    block : int
        Candidates tested per call (a power of two keeps the sequence balanced).

    Returns
    -------
    (k, d) float, k = n unless ``max_candidates`` ran out first
    """
    sobol = qmc.Sobol(dimension, scramble=True, seed=np.random.default_rng(seed))
    kept, n_kept, drawn = [], 0, 0
    while n_kept < n and drawn < max_candidates:
        X = sobol.random(block)
        drawn += block
        ok = np.asarray(validity(X), dtype=bool)
        kept.append(X[ok][: n - n_kept])
        n_kept += len(kept[-1])
    return np.vstack(kept) if kept else np.empty((0, dimension))


def simulated_outcomes(recorded, X: np.ndarray, chunk: int = 1024,
                       on_chunk: Callable[[int], None] | None = None):
    """Simulate the rows of ``X`` through ``recorded`` (a
    :class:`~rgmcad.runs.store.RecordedProblem`: journaled, replayed when known) in chunks.

    Returns
    -------
    success, valid : (n,) bool
    seconds : float
        Their simulation time. ``on_chunk(done)`` is called after each chunk.
    """
    success, valid, seconds = [], [], 0.0
    for i in range(0, len(X), chunk):
        records = recorded.simulate_records(X[i:i + chunk])
        success += [r.outcome is Outcome.SUCCESS for r in records]
        valid += [r.valid for r in records]
        seconds += sum(r.seconds for r in records)
        if on_chunk is not None:
            on_chunk(min(i + chunk, len(X)))
    return np.array(success, dtype=bool), np.array(valid, dtype=bool), seconds


def local_points(x: np.ndarray, n: int, rng: np.random.Generator, eta: float = ETA) -> np.ndarray:
    """``n`` points uniform in the L-infinity cube ``x +- eta`` intersected with ``[0, 1]^d``."""
    x = np.asarray(x, dtype=float).reshape(-1)
    low, high = np.clip(x - eta, 0, 1), np.clip(x + eta, 0, 1)
    return low + rng.random((n, len(x))) * (high - low)


def balls_of(x: np.ndarray, points: np.ndarray, eps: np.ndarray = EPS_GRID,
             eta: float = ETA) -> np.ndarray:
    """(m,) int: for each point the index of the smallest ball ``|y - x| <= eps_k + eta``
    holding it, ``len(eps)`` for none."""
    dist = np.linalg.norm(np.atleast_2d(points) - np.asarray(x, dtype=float), axis=1)
    return np.searchsorted(np.asarray(eps) + eta, dist, side="left")


def dense_curve(x: np.ndarray, points: np.ndarray, success: np.ndarray,
                local: np.ndarray | None = None, local_success: np.ndarray | None = None, *,
                eps: np.ndarray = EPS_GRID, eta: float = ETA, z: float = 1.959964,
                boot: int = 400, rng: np.random.Generator | int | None = 0) -> RobustnessCurve:
    """``rho_l(x, eps)`` and ``rho_g`` from valid simulated points (see the module docstring).

    Parameters
    ----------
    x : (d,) float
    points : (n, d) float
        The dense set's valid points; ``success`` (n,) bool their outcomes.
    local, local_success : optional
        ``x``'s local points (valid ones) and their outcomes.
    boot : int
        Poisson-bootstrap replicates of the points for ``rho_g``'s interval (the balls are
        nested, so their estimates are not independent and the normal approximation of
        :mod:`~rgmcad.runs.robustness` would understate it).

    Returns
    -------
    RobustnessCurve
        ``simulations`` counts the local points only (the dense set is shared);
        ``validity_tests`` is 0.
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    eps = np.asarray(eps, dtype=float)
    P, S = np.atleast_2d(points), np.asarray(success, dtype=bool)
    n_local = 0
    if local is not None and len(local):
        n_local = len(local)
        P = np.vstack([P, np.atleast_2d(local)])
        S = np.concatenate([S, np.asarray(local_success, dtype=bool)])
    k = balls_of(x, P, eps, eta)
    inside = k < len(eps)
    k, S = k[inside], S[inside]
    weights = trapezoid_weights(eps)

    def curve(w):  # w: (b, m) weights of the points; (b, k) counts and successes per ball
        counts = np.cumsum(np.stack([np.bincount(k, wi, len(eps)) for wi in w]), axis=1)
        succ = np.cumsum(np.stack([np.bincount(k, wi * S, len(eps)) for wi in w]), axis=1)
        return counts, succ, np.where(counts > 0, succ / np.maximum(counts, 1e-12), 0.0)

    counts, succ, rho = (a[0] for a in curve(np.ones((1, len(k)))))
    gen = np.random.default_rng(rng)
    rho_g = float(dot(weights, rho))
    se = float((curve(gen.poisson(1.0, (boot, len(k))))[2] @ weights).std(ddof=1)) \
        if boot > 1 and len(k) else 0.5
    low, high = wilson_interval(succ.astype(int), counts.astype(int), z)
    return RobustnessCurve(
        x=x, eps=eps, successes=succ.astype(int), counts=counts.astype(int), rho=rho,
        low=low, high=high, rho_g=rho_g, rho_g_low=max(0.0, rho_g - z * se),
        rho_g_high=min(1.0, rho_g + z * se), simulations=n_local, validity_tests=0, eta=eta)
