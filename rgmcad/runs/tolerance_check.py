"""Placement tolerances a maker can trust: the model's, each side then simulated.

The learnt model says how far each free parameter may move, alone, before the predicted
success drops (:func:`~rgmcad.learning.placement_tolerance`). A model can be confidently wrong
(a user's ``track1.x`` was printed +51 mm and failed at +45 mm), so every side is simulated
before it is printed: the layout with that one parameter moved to ``POINTS`` evenly spaced
places up to the bound, each a whole number of 0.1 mm or 0.1 degree (the printed resolution).
A side where one of them fails is narrowed to the last place that succeeded, refined by
``BISECTIONS`` halvings towards the first that failed; the side printed then succeeds at its
bound, the very number printed, and at every place checked before it.

The simulations are the run's (journaled, so an interrupted run replays them), under the
run's physics; a side that reaches the end of its range or stops where parts meet is checked
like any other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["POINTS", "BISECTIONS", "CheckedTolerances", "check_tolerances"]

POINTS = 4
"""Places simulated along each side, the bound the last: a quarter, half, three quarters."""

BISECTIONS = 4
"""Halvings between the last place that succeeded and the first that failed: a narrowed side
is within 1/64 of the model's tolerance (or 0.1 mm) of where the layout starts failing."""


@dataclass(frozen=True)
class CheckedTolerances:
    """Result of :func:`check_tolerances`.

    Attributes
    ----------
    tolerances : (d, 2) float
        ``[[down, up], ...]`` normalised: the model's where every place simulated succeeded,
        else the narrowed side.
    narrowed : (d, 2) bool
        Sides where a simulated place failed.
    simulations : int
        Layouts simulated (places and halvings).
    """

    tolerances: np.ndarray
    narrowed: np.ndarray
    simulations: int


def check_tolerances(x: np.ndarray, tolerances: np.ndarray,
                     succeeds: Callable[[np.ndarray], np.ndarray], step: np.ndarray,
                     points: int = POINTS, bisections: int = BISECTIONS) -> CheckedTolerances:
    """Simulate each side of ``tolerances`` around ``x`` and narrow the sides that fail.

    Every place simulated is a whole number of ``step`` from ``x``, the model's tolerance
    rounded down to one: the number printed (to 0.1 mm or 0.1 degree) is a place simulated,
    not a neighbour of one (between neighbours 0.1 mm apart a chain can fail).

    Parameters
    ----------
    x : (d,) float
        The layout, normalised.
    tolerances : (d, 2) float
        The model's ``[[down, up], ...]``, normalised, >= 0.
    succeeds : ``(n, d) -> (n,) bool``
        Whether each layout succeeds in simulation (an invalid layout does not); called once
        for all the places, then once per halving.
    step : (d,) float
        The resolution of each parameter as printed, normalised (0.1 mm or 0.1 degree over
        the parameter's range).
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    step = np.broadcast_to(np.asarray(step, dtype=float), x.shape)
    whole = np.floor(np.asarray(tolerances, dtype=float).reshape(len(x), 2)
                     / step[:, None] + 1e-6).astype(int)  # steps of each side
    sides = [(j, k) for j in range(len(x)) for k in range(2) if whole[j, k] > 0]

    def moved(side, n):
        j, k = side
        p = x.copy()
        p[j] = np.clip(x[j] + (n if k else -n) * step[j], 0.0, 1.0)
        return p

    places = {s: sorted({max(1, int(whole[s] * f)) for f in np.arange(1, points + 1) / points})
              for s in sides}
    batch = [(s, n) for s in sides for n in places[s]]
    ok = (np.asarray(succeeds(np.array([moved(s, n) for s, n in batch])), dtype=bool)
          if batch else np.zeros(0, bool))
    simulations = len(batch)
    first_failure: dict = {}
    for (s, n), o in zip(batch, ok, strict=True):
        if not o and s not in first_failure:
            first_failure[s] = n
    good = {s: max([0] + [n for n in places[s] if n < bad]) for s, bad in first_failure.items()}
    bad = dict(first_failure)
    for _ in range(bisections):
        keys = [s for s in bad if bad[s] - good[s] > 1]
        if not keys:
            break
        mids = [(good[s] + bad[s]) // 2 for s in keys]
        ok = np.asarray(succeeds(np.array([moved(s, m) for s, m in zip(keys, mids,
                                                                         strict=True)])), bool)
        simulations += len(keys)
        for s, m, o in zip(keys, mids, ok, strict=True):
            (good if o else bad)[s] = m
    out = whole.astype(float)
    narrowed = np.zeros(out.shape, dtype=bool)
    for s in bad:
        out[s], narrowed[s] = good[s], True
    return CheckedTolerances(out * step[:, None], narrowed, simulations)
