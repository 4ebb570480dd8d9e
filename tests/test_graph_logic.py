"""The learner follows the causal graph's logic: an any-join is an OR of its parent paths."""

from __future__ import annotations

import numpy as np
import pytest

from rgmcad.learning import (
    BoxRegion,
    ConstantModel,
    LearningSettings,
    OracleEvent,
    ProductOracle,
    SPDModel,
    SuccessLogic,
    learn_and_optimize,
)

FAST = LearningSettings(svm_C_grid=(1.0, 10.0, 100.0, 1000.0), svm_gamma_grid=(0.1, 1.0, 10.0),
                        svm_class_weights=(None,))

# start -> left, start -> right; `through` wakes when either path arrived; then `land`
DIAMOND = {"start": (), "left": ("start",), "right": ("start",), "through": ("left", "right"),
           "land": ("through",)}


def fork_oracle(softness=0.0):
    """Two alternative paths in x0: the left one succeeds for x0 < 0.3, the right one for
    x0 > 0.7; either carries the chain on. `land` needs x1 in [0.2, 0.8]."""
    return ProductOracle(2, {
        "start": OracleEvent(),
        "left": OracleEvent(("start",), (0,), BoxRegion((0.0,), (0.3,))),
        "right": OracleEvent(("start",), (0,), BoxRegion((0.7,), (1.0,))),
        "through": OracleEvent(("left", "right"), join="any"),
        "land": OracleEvent(("through",), (1,), BoxRegion((0.2,), (0.8,))),
    }, softness=softness)


def constant_model(graph, any_joins, **p):
    models = {e: ConstantModel(p[e], "test") for e in graph}
    return SPDModel(tuple(graph), models, True, logic=SuccessLogic(graph, frozenset(any_joins)))


def test_all_joins_are_the_papers_product():
    logic = SuccessLogic(DIAMOND)
    assert logic.is_conjunction
    assert [r.name for r in logic.requirements] == list(DIAMOND)
    p = {e: np.array([v]) for e, v in zip(DIAMOND, (0.9, 0.5, 0.4, 0.8, 0.7), strict=True)}
    np.testing.assert_allclose(logic.probability(p), 0.9 * 0.5 * 0.4 * 0.8 * 0.7)


def test_or_probability_counts_a_shared_ancestor_once():
    logic = SuccessLogic(DIAMOND, frozenset({"through"}))
    assert not logic.is_conjunction
    assert [r.name for r in logic.requirements] == ["start", "any(left, right)", "through", "land"]
    p = {e: np.array([v]) for e, v in zip(DIAMOND, (0.9, 0.5, 0.4, 0.8, 0.7), strict=True)}
    np.testing.assert_allclose(logic.probability(p), 0.9 * (1 - 0.5 * 0.6) * 0.8 * 0.7)


@pytest.mark.parametrize("any_joins", [set(), {"join"}, {"join", "late"}])
def test_success_probability_matches_the_simulated_frequency(any_joins):
    # A graph where paths share events and re-merge twice: r -> a -> a2, r -> b, a -> x;
    # join waits for a2 and b; late waits for join and x. Soft regions give fractional
    # probabilities everywhere; the oracle draws each event independently, as the model
    # assumes, so the predicted mean success must match the simulated frequency.
    events = {
        "r": OracleEvent((), (0,), BoxRegion((0.1,), (2.0,))),
        "a": OracleEvent(("r",), (1,), BoxRegion((0.5,), (2.0,))),
        "a2": OracleEvent(("a",), (0,), BoxRegion((-1.0,), (0.6,))),
        "b": OracleEvent(("r",), (1,), BoxRegion((-1.0,), (0.4,))),
        "x": OracleEvent(("a",), (0,), BoxRegion((0.3,), (2.0,))),
        "join": OracleEvent(("a2", "b"), (1,), BoxRegion((0.2,), (2.0,)),
                            join="any" if "join" in any_joins else "all"),
        "late": OracleEvent(("join", "x"), join="any" if "late" in any_joins else "all"),
    }
    oracle = ProductOracle(2, events, softness=0.3, seed=3)
    X = np.random.default_rng(0).random((20000, 2))
    simulated = np.mean([lab.success for lab in oracle.simulate(X)])
    predicted = oracle.global_probability(X).mean()
    # 20000 Bernoulli draws: the standard error is below 0.0036
    assert abs(simulated - predicted) < 0.011, (simulated, predicted)
    if any_joins:  # the product of the factors, the old rule, is far off
        product = np.prod(np.stack(list(oracle.success_probability(X).values())), axis=0).mean()
        assert abs(simulated - product) > 0.03


def test_weakest_link_names_the_group_of_alternatives_or_the_event():
    joins = {"through"}
    # left 0.3, right 0.2: one of them succeeds with 0.44, which beats neither alone
    m = constant_model(DIAMOND, joins, start=1.0, left=0.3, right=0.2, through=0.9, land=0.95)
    name, p = m.weakest_link(np.zeros(2))
    assert name == "any(left, right)" and p == pytest.approx(0.44)
    assert float(m.success_proba(np.zeros((1, 2)))[0]) == pytest.approx(0.44 * 0.9 * 0.95)
    # a required event weaker than the group is the weakest link, not the weaker path
    m = constant_model(DIAMOND, joins, start=1.0, left=0.3, right=0.2, through=0.4, land=0.95)
    assert m.weakest_link(np.zeros(2)) == ("through", pytest.approx(0.4))


def test_objective_gradient_through_a_group_of_alternatives():
    oracle = fork_oracle(softness=0.05)
    rng = np.random.default_rng(0)
    settings = FAST.replace(n_initial=200, n_successes=40, exploration_batch=10, active_batch=5,
                            active_max_iter=1, include_certain_events=True)
    res = learn_and_optimize(oracle, settings, rng)
    model = res.model
    assert model.logic is not None and not model.logic.is_conjunction
    x = np.array([0.55, 0.35])
    offsets = 0.03 * np.random.default_rng(1).standard_normal((8, 2))
    value, grad = model.objective(x, offsets)
    h = 1e-6
    numeric = [(model.objective(x + h * e, offsets)[0] - model.objective(x - h * e, offsets)[0])
               / (2 * h) for e in np.eye(2)]
    np.testing.assert_allclose(grad, numeric, rtol=1e-3, atol=1e-6)


def test_optimising_a_graph_with_alternatives_finds_a_layout_that_works():
    # The two paths exclude each other: the product of their factors is near 0 everywhere,
    # so a learner that multiplies every factor sees no layout worth having.
    oracle = fork_oracle()
    settings = FAST.replace(n_initial=128, n_successes=30, exploration_batch=10, active_batch=5,
                            active_max_iter=2)
    res = learn_and_optimize(oracle, settings, np.random.default_rng(0))
    assert oracle.simulate(res.x[None])[0].success
    assert res.probability > 0.7
    factors = res.model.event_probabilities(res.x[None])
    assert float(factors["left"][0] * factors["right"][0]) < 0.2  # what the product would say
    assert res.weakest_event in {"any(left, right)", "land", "through", "start"}
    # the layout is inside one path's region and away from its edges, and x1 centred
    x0, x1 = res.x
    assert (x0 < 0.3 or x0 > 0.7) and 0.3 < x1 < 0.7
