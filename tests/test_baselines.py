"""The paper's baselines and CMA-ES (rgmcad.learning.baselines) on synthetic problems with a
known answer: what they find, the simulations they use (counted at the simulator), and
their determinism."""

from __future__ import annotations

import numpy as np
import pytest

from rgmcad.learning import BASELINES, BaselineResult, cmaes_search, gp_search, random_search
from rgmcad.learning.oracles import (
    BallRegion,
    BoxRegion,
    OracleEvent,
    ProductOracle,
    SlabRegion,
)

# gp_search with a cheaper acquisition search than its defaults (the authors' 25 kernel
# restarts and 100 000 warm-up points cost seconds per step): same algorithm
FAST = {"b3": {"n_restarts": 2, "n_warmup": 4000, "n_starts": 2}}


def _run(name, problem, budget, seed):
    return BASELINES[name](problem, budget, seed, **FAST.get(name, {}))


class Counting:
    """A problem that counts what the method asks of its simulator."""

    def __init__(self, problem):
        self.p = problem
        self.dimension, self.event_parents = problem.dimension, problem.event_parents
        self.any_joins = problem.any_joins
        self.simulations = 0

    def validity(self, X):
        return self.p.validity(X)

    def penetration(self, x):
        return self.p.penetration(x)

    def simulate(self, X):
        self.simulations += len(np.atleast_2d(X))
        return self.p.simulate(X)


def two_regions() -> ProductOracle:
    """Success in a thin slab (|x0 - 0.2| <= 0.03: lucky hits, rho(0.1) about 0.3) or a ball
    (centre (0.7, 0.5), radius 0.15: its centre's 0.1-cube lies inside); an invalid ball."""
    events = {
        "thin": OracleEvent(dims=(0,), region=SlabRegion((1.0,), 0.2, 0.03)),
        "round": OracleEvent(dims=(0, 1), region=BallRegion((0.7, 0.5), 0.15)),
        "goal": OracleEvent(parents=("thin", "round"), join="any"),
    }
    return ProductOracle(2, events, invalid_balls=(((0.4, 0.8), 0.12),))


def box_oracle(lo=0.45, hi=0.85, d=2) -> ProductOracle:
    return ProductOracle(d, {"a": OracleEvent(dims=tuple(range(d)), region=BoxRegion(
        (lo,) * d, (hi,) * d))}, invalid_balls=(((0.2,) * d, 0.15),))


def _in_round(x) -> bool:
    return float(np.linalg.norm(np.asarray(x) - [0.7, 0.5])) <= 0.15


def test_random_search_returns_its_first_success_and_stops_there():
    problem = Counting(box_oracle())
    r = random_search(problem, 500, 0, batch=4)
    assert problem.p.global_probability(r.x[None])[0] == 1.0 and r.score == 1.0
    assert r.n_simulations == problem.simulations < 500 and r.n_simulations % 4 == 0
    first = np.flatnonzero(r.history[:, -1] == 1)[0]
    assert np.array_equal(r.history[first, :-1], r.x)  # the first success in draw order
    assert np.array_equal(random_search(box_oracle(), 500, 0, batch=1).x, r.x)  # any batch


@pytest.mark.parametrize("name", ["b2", "b3", "cma"])
def test_robustness_searches_prefer_the_robust_region_over_lucky_hits(name):
    """Both regions hold successes; only the ball's centre is robust. Over three seeds the
    method returns a layout in the ball each time."""
    problem = two_regions()
    found = [_run(name, problem, 300, seed) for seed in range(3)]
    assert all(_in_round(r.x) for r in found), [r.x for r in found]
    assert all(r.score >= 0.8 for r in found)


@pytest.mark.parametrize("name", list(BASELINES))
@pytest.mark.parametrize("budget", [3, 23, 60])
def test_budgets_are_respected_exactly(name, budget):
    """Simulations counted at the simulator equal what the method reports, never past the
    budget; a scoring method spends whole scores of d^2 + 1 (a budget under one score buys one
    smaller score)."""
    problem = Counting(box_oracle())
    r = _run(name, problem, budget, 1)
    assert isinstance(r, BaselineResult) and r.budget == budget
    assert r.n_simulations == problem.simulations <= budget
    if name != "b1":
        per_score = min(5, budget)
        assert r.n_simulations == (budget // per_score) * per_score
        assert r.n_evaluations == budget // per_score


def test_random_search_without_success_spends_the_whole_budget():
    problem = Counting(box_oracle(lo=2.0, hi=3.0))  # the region lies outside the cube
    r = random_search(problem, 37, 5)
    assert problem.simulations == r.n_simulations == 37 and r.score == 0.0
    assert problem.p.validity(r.x[None])[0]


@pytest.mark.parametrize("name", list(BASELINES))
def test_the_same_seed_gives_the_same_result(name):
    problem = two_regions()
    a, b, c = (_run(name, problem, 60, s) for s in (7, 7, 8))
    assert np.array_equal(a.x, b.x) and np.array_equal(a.history, b.history)
    assert a.n_simulations == b.n_simulations
    assert not np.array_equal(a.history, c.history)


def test_gp_and_cmaes_leave_invalid_proposals_unscored():
    """A design space mostly invalid: proposals there cost no simulation."""
    problem = Counting(ProductOracle(2, {"a": OracleEvent(dims=(0, 1), region=BoxRegion(
        (0.0, 0.0), (0.3, 0.3)))}, invalid_balls=(((0.7, 0.7), 0.6),)))
    for method, kw in ((gp_search, FAST["b3"]), (cmaes_search, {})):
        problem.simulations = 0
        r = method(problem, 40, 3, **kw)
        assert r.n_simulations == problem.simulations == 40
        assert problem.p.validity(r.x[None])[0]


def test_a_bad_budget_is_refused():
    for bad in (0, -1, 2.5, True):
        with pytest.raises(ValueError, match="budget"):
            random_search(box_oracle(), bad, 0)
