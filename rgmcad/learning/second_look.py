"""A second look: learn again from the final choice's own simulations, refine again, and
keep the refined layout only if it beats the chosen one by simulation.

The success model is fitted before the final choice, on the exploration and active-learning
samples; the final choice then simulates every candidate at a few hundred errors around it
(:mod:`rgmcad.learning.verify`), which is the densest sampling the run makes of the place the
layout will be built in, and the model never sees it. Here the model is fitted again on every
simulation of the run (no new active learning), the refinement runs again from the chosen
layout and from the new model's best starts, and the layout it finds races the chosen one on
a design of errors neither has met (the chosen layout's rate at the final choice's errors is
the highest of several noisy estimates, so it reads high). Ties keep the chosen layout, and
a refined layout that fails its own simulation is moved by a hair as an optimum is, else
left out: the layout returned is never one the simulator rated lower.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .errors import design_from_settings
from .factorize import fit_spd
from .optimize import maximize_robustness, place_unmodelled, start_points
from .verify import _MOST_ERRORS, Candidate, _nudged, _raced, outcome

__all__ = ["SecondLook", "second_look"]

# the errors of the check: independent of the final choice's (scramble 0 is theirs, 1 the
# errors a race adds while copies are mostly invalid)
_CHECK_ERRORS_SEED, _CHECK_MORE_SEED = 2, 3


@dataclass(frozen=True)
class SecondLook:
    """What :func:`second_look` did.

    Attributes
    ----------
    chosen : Candidate
        The layout to use: ``refined`` if it won the check, else the layout it started from.
    check : (Candidate, Candidate) or None
        The layout it started from and the refined one, with their success rates at the
        check's errors (None when the refinement did not move the layout or nothing near
        the refined layout succeeds).
    n_simulations : int
        Simulations this step ran.
    """

    chosen: Candidate
    check: tuple[Candidate, Candidate] | None
    n_simulations: int


def second_look(problem, model_settings, X: np.ndarray, labels, chosen: Candidate, simulate,
                rng: np.random.Generator) -> SecondLook:
    """Refit on ``X`` (n, d) with ``labels`` (every simulation of the run), refine from
    ``chosen`` and the new model's starts, and race the result against ``chosen`` (see the
    module docstring). ``problem`` gives ``event_parents``, ``any_joins``, ``validity`` and
    ``penetration``; ``simulate(P) -> labels``; ``rng`` is the fit's only randomness."""
    s = model_settings
    X = np.asarray(X, dtype=float)

    def no_simulation(Q, stage):  # active learning is off: nothing is asked
        raise RuntimeError("the second look's fit asked for simulations")

    model = fit_spd(X, labels, problem.event_parents, problem.validity, no_simulation,
                    s.replace(active_max_iter=0), rng, any_joins=problem.any_joins).model
    valid = np.flatnonzero([lab.valid for lab in labels])
    starts = [chosen.x] + [X[valid[r]] for r in start_points(model, X[valid], s)]
    best = max((maximize_robustness(model, problem.penetration, x0, s) for x0 in starts),
               key=lambda r: r.objective)
    x = best.x
    if s.unmodelled_at == "median":
        x = place_unmodelled(model, x, X[[k for k, lab in enumerate(labels) if lab.success]],
                             problem.penetration)
    if np.array_equal(x, chosen.x):
        return SecondLook(chosen, None, 0)
    source = f"refined again from {chosen.source}"
    own = simulate(x[None, :])[0]
    refined, n_sims = Candidate(x, source, outcome(own)), 1
    if not own.success:
        refined, n_nudges = _nudged(x, simulate, problem.validity, source)
        n_sims += n_nudges
        if refined is None:
            return SecondLook(chosen, None, n_sims)
    d = len(x)
    design = design_from_settings(d, s, s.verify_samples, s.verify_noise,
                                  scramble=_CHECK_ERRORS_SEED)
    n = len(design.offsets)
    more = design_from_settings(d, s, _MOST_ERRORS * n, s.verify_noise, scramble=_CHECK_MORE_SEED)
    unrated = dict(success_rate=float("nan"), n_valid=0)
    tested, n_tested, best_index, _ = _raced(
        [replace(chosen, **unrated), replace(refined, **unrated)], design, simulate,
        problem.validity, more=more.interleaved().head((_MOST_ERRORS - 1) * n))
    before, after = tested
    return SecondLook(after if best_index == 1 else chosen, (before, after), n_sims + n_tested)
