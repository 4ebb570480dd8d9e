"""Design centring by simulation: move a working layout away from the edges of its success
region.

When the exploration found few successes, the success model is poor and the layout the final
choice keeps is often a simulated success in a small pocket of the region, close to where it
ends. Gaussian adaptation (Kjellström's algorithm for maximising the yield of a design)
moves it by simulation alone: draw layouts around the current centre ``m`` from an isotropic
Gaussian of radius ``r`` (standard deviation ``r / sqrt(d)`` per coordinate, so that the
typical distance of a draw is ``r``, the unit of ``rho_l``'s balls); move ``m`` part of the
way to the mean of the draws that succeeded; grow ``r`` when more than the target fraction
of draws succeed, shrink it when fewer do. The mean of the successes minus ``m`` is
``(r^2 / d) grad log P_r(m)``, with ``P_r`` the success rate of the Gaussian at ``m``: the
centre climbs the success rate under errors of the radius it is tested at, and the radius
settles where the region holds the target rate, so it grows as the centre moves in.

Draws are made like the errors of :mod:`rgmcad.learning.errors`: a coordinate that leaves
``[0, 1]`` is mirrored back; invalid layouts (bodies overlap) are never simulated, as in
``rho_l``, which leaves them out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .errors import mirrored_offsets
from .oracles import Label

__all__ = ["Centering", "center_layout"]

_CANDIDATES_PER_DRAW = 4  # validity tests per wanted valid draw before a batch gives up
_MIN_RADIUS, _MAX_RADIUS = 1e-3, 1.0


@dataclass(frozen=True)
class Centering:
    """What :func:`center_layout` did.

    Attributes
    ----------
    x : (d,) float
        The last centre (valid; not simulated here).
    centres : (k + 1, d) float
        The centre before each batch, then the last one.
    radii : (k,) float
        The radius each batch was drawn at.
    hit_rates : (k,) float
        The fraction of each batch's draws that succeeded (nan for a batch with no valid
        draw, which was not simulated).
    n_simulations : int
    """

    x: np.ndarray
    centres: np.ndarray
    radii: np.ndarray
    hit_rates: np.ndarray
    n_simulations: int


def center_layout(
    x0: np.ndarray,
    simulate: Callable[[np.ndarray], list[Label]],
    validity: Callable[[np.ndarray], np.ndarray],
    rng: np.random.Generator,
    *,
    simulations: int,
    batch: int = 16,
    hit_rate: float = 0.3,
    radius: float = 0.02,
    learning_rate: float = 0.5,
) -> Centering:
    """Gaussian adaptation from ``x0`` (see the module docstring).

    Parameters
    ----------
    x0 : (d,) float in [0, 1]^d
        A valid layout (normally one that succeeded).
    simulate : callable
        ``simulate(P) -> list[Label]``, one per row.
    validity : callable
        ``validity(P) -> (k,) bool``.
    rng : numpy.random.Generator
        The only source of randomness.
    simulations : int
        At most this many simulations (whole batches).
    batch : int
        Valid draws per batch.
    hit_rate : float in (0, 1)
        The fraction of successes the radius is adapted to.
    radius : float
        The first batch's radius (normalised units); it then adapts within [0.001, 1].
    learning_rate : float in (0, 1]
        The share of the way to the successes' mean the centre moves per batch.
    """
    m = np.asarray(x0, dtype=float).copy()
    r = float(np.clip(radius, _MIN_RADIUS, _MAX_RADIUS))
    centres, radii, rates = [m.copy()], [], []
    n_sims = 0
    while n_sims + batch <= simulations:
        P = _draws(m, r, batch * _CANDIDATES_PER_DRAW, rng)
        ok = np.flatnonzero(np.asarray(validity(P), dtype=bool))[:batch]
        radii.append(r)
        if len(ok) == 0:  # every draw overlaps: look closer, unless as close as it gets
            rates.append(float("nan"))
            centres.append(m.copy())
            if r == _MIN_RADIUS:
                break
            r = max(r / 2, _MIN_RADIUS)
            continue
        wins = np.array([lab.success for lab in simulate(P[ok])], dtype=bool)
        n_sims += len(ok)
        p = float(wins.mean())
        rates.append(p)
        if wins.any():
            step = learning_rate * (P[ok][wins].mean(axis=0) - m)
            for _ in range(4):  # a centre whose bodies overlap is no layout: move less
                if bool(np.asarray(validity((m + step)[None, :]))[0]):
                    m = m + step
                    break
                step = step / 2
        # x2 after a batch of successes only, /1.35 after one without any
        r = float(np.clip(r * np.exp(p - hit_rate), _MIN_RADIUS, _MAX_RADIUS))
        centres.append(m.copy())
    return Centering(m, np.array(centres), np.array(radii), np.array(rates), n_sims)


def _draws(m: np.ndarray, r: float, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` layouts ``m + r z / sqrt(d)``, each coordinate leaving the cube mirrored back
    (then clipped, for one past both faces)."""
    d = len(m)
    half = rng.standard_normal(((n + 1) // 2, d)) * (r / np.sqrt(d))
    offsets = np.stack([half, -half], axis=1).reshape(-1, d)[:n]
    return np.clip(m + mirrored_offsets(m, offsets), 0.0, 1.0)
