"""Choosing the layout to hand to the builder: simulate the optimum and a few alternatives
under errors, keep the one that works most often.

The refinement (section 7) maximises a *model's* prediction; the model can be confidently
wrong where it has few samples, and then the optimum fails or works only at the exact point.
So the final choice is made by the simulator: each candidate (the optimum, and the simulated
global successes the model rates highest under the refinement's errors) must succeed
itself, and is then simulated at ``verify_samples`` errors of a fixed design
(:mod:`rgmcad.learning.errors`, the same for every candidate): Gaussian placement errors of
standard deviation ``verify_noise``, copies outside the design space clipped onto it; or,
with ``error_radius`` > 0, the errors of global robustness, kept in the design space with
their importance weights. Invalid copies are left out. The candidate with the highest
success rate among its valid copies (per radius, then averaged over radii, for ball errors)
wins; ties go to the earlier candidate, so the optimum first. With ``verify_samples = 0`` the choice is the
paper's: the optimum if it succeeds, else the best predicted simulated success.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .errors import design_from_settings, expected_success
from .factorize import SPDModel
from .oracles import Label
from .settings import LearningSettings

__all__ = ["Candidate", "Verification", "verify_layout"]


def outcome(label: Label) -> str:
    """``"invalid"``, ``"success"`` or ``"failure"``."""
    return "invalid" if not label.valid else "success" if label.success else "failure"


@dataclass(frozen=True)
class Candidate:
    """One layout considered for the result.

    Attributes
    ----------
    x : (d,) float
    source : str
        ``"optimum"`` or ``"simulated sample #i"`` (row of the run's samples).
    outcome : str
        Its own simulation: ``"success"``, ``"failure"`` or ``"invalid"``.
    success_rate : float
        Success rate of its valid perturbed copies (nan when not tested).
    n_valid : int
        Valid perturbed copies simulated.
    """

    x: np.ndarray
    source: str
    outcome: str
    success_rate: float = float("nan")
    n_valid: int = 0


@dataclass(frozen=True)
class Verification:
    """Result of :func:`verify_layout`.

    Attributes
    ----------
    chosen : Candidate
        The layout to use; ``verified`` says whether it succeeded in simulation.
    verified : bool
        False only when no simulated layout succeeded at all (``chosen`` is then the
        optimum).
    optimum : Candidate
    candidates : tuple of Candidate
        Every candidate tested under placement errors, in order.
    n_simulations : int
        Simulations this step ran (or replayed).
    """

    chosen: Candidate
    verified: bool
    optimum: Candidate
    candidates: tuple[Candidate, ...]
    n_simulations: int


def verify_layout(
    model: SPDModel,
    x_opt: np.ndarray,
    X: np.ndarray,
    labels: Sequence[Label],
    simulate: Callable[[np.ndarray], list[Label]],
    validity: Callable[[np.ndarray], np.ndarray],
    settings: LearningSettings,
) -> Verification:
    """Pick the layout to return (see the module docstring).

    Parameters
    ----------
    model : SPDModel
        Ranks the simulated successes.
    x_opt : (d,) float
        The refinement's optimum.
    X : (n, d) float
        Every simulated sample of the run, with ``labels`` their labels.
    simulate : callable
        ``simulate(P) -> list[Label]``, one per row of ``P``.
    validity : callable
        ``validity(P) -> (k,) bool``.
    settings : LearningSettings
        ``verify_candidates``, ``verify_samples``, ``verify_noise``.
    """
    x_opt = np.asarray(x_opt, dtype=float)
    X = np.asarray(X, dtype=float).reshape(len(labels), -1)
    own = simulate(x_opt[None, :])[0]
    optimum = Candidate(x_opt, "optimum", outcome(own))
    n_sims = 1

    d = len(x_opt)
    successes = [i for i, lab in enumerate(labels) if lab.success and not np.array_equal(X[i], x_opt)]
    rating = design_from_settings(d, settings, settings.placement_samples,
                                  settings.placement_noise)
    order = (np.argsort(-expected_success(model, X[successes], rating), kind="stable")
             if successes else [])
    n_alternatives = settings.verify_candidates - (1 if own.success else 0)
    candidates = ([optimum] if own.success else []) + [
        Candidate(X[successes[k]], f"simulated sample #{successes[k]}", "success")
        for k in order[: max(n_alternatives, 0)]
    ]
    if not candidates:
        return Verification(optimum, False, optimum, (), n_sims)
    if settings.verify_samples == 0 or len(candidates) == 1:
        return Verification(candidates[0], True, optimum, (), n_sims)

    design = design_from_settings(d, settings, settings.verify_samples, settings.verify_noise)
    errors = [design.at(c.x) for c in candidates]
    # Gaussian copies outside the design space are clipped onto it; ball copies are kept
    # inside by design.at (raw weight 0 for the few it cannot)
    P = np.vstack([np.clip(c.x + offsets, 0.0, 1.0) for c, (offsets, _) in
                   zip(candidates, errors, strict=True)])
    raw = np.concatenate([r for _, r in errors])
    ok = raw > 0
    ok[ok] = np.asarray(validity(P[ok]), dtype=bool)  # invalid copies are left out
    results = iter(simulate(P[ok]))
    n_sims += int(ok.sum())
    tested = []
    for c, block_ok, block_raw in zip(candidates, np.split(ok, len(candidates)),
                                      np.split(raw, len(candidates)), strict=True):
        wins = np.zeros(len(block_ok))
        wins[block_ok] = [next(results).success for _ in range(int(block_ok.sum()))]
        rate = float(design.normalized(block_raw * block_ok) @ wins)
        tested.append(Candidate(c.x, c.source, c.outcome, rate, int(block_ok.sum())))
    best = max(range(len(tested)), key=lambda k: (tested[k].success_rate, -k))
    return Verification(tested[best], True, optimum, tuple(tested), n_sims)
