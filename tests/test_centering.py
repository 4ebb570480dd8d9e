"""Centring a working layout by simulation (rgmcad.learning.centering) and its place in the
final choice: a layout near the edge of its success region moves in, never into overlapping
bodies, within the budget, and replaces the chosen layout only when it does better."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rgmcad.learning import LearningSettings, verify_layout
from rgmcad.learning.centering import center_layout
from rgmcad.learning.oracles import BallRegion, BoxRegion, OracleEvent, ProductOracle

SIMPLE = str(Path(__file__).resolve().parent.parent / "scenarios" / "simple.toml")


def ball_oracle(d, invalid=()):
    """Success iff within 0.3 of the middle of the cube."""
    return ProductOracle(d, {"hit": OracleEvent((), tuple(range(d)),
                                                BallRegion((0.5,) * d, 0.3))},
                         invalid_balls=invalid)


class Counting:
    """The oracle's simulate, keeping every layout it was asked for."""

    def __init__(self, oracle):
        self.oracle = oracle
        self.asked: list[np.ndarray] = []

    def __call__(self, X):
        self.asked.append(np.atleast_2d(X))
        return self.oracle.simulate(X)

    @property
    def layouts(self):
        return np.vstack(self.asked)


def edge_point(d, depth, seed):
    """A point ``depth`` inside the 0.3 ball around the middle, in a random direction."""
    u = np.random.default_rng(seed).standard_normal(d)
    return 0.5 + (0.3 - depth) * u / np.linalg.norm(u)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_layout_at_the_edge_moves_deep_inside(seed):
    oracle = ball_oracle(8)
    simulate = Counting(oracle)
    x0 = edge_point(8, 0.03, seed)
    out = center_layout(x0, simulate, oracle.validity, np.random.default_rng(seed),
                        simulations=320)
    depth = float(oracle.events["hit"].region.signed_distance(out.x[None, :])[0])
    assert depth > 0.12  # from 0.03 of the 0.3 possible; measured 0.16-0.24
    assert out.n_simulations == len(simulate.layouts) <= 320
    assert len(out.radii) == len(out.hit_rates) == len(out.centres) - 1
    assert out.radii[-1] > 0.1  # the radius grew with the room around the centre


def test_the_middle_of_a_symmetric_region_stays_put():
    oracle = ball_oracle(6)
    out = center_layout(np.full(6, 0.5), oracle.simulate, oracle.validity,
                        np.random.default_rng(0), simulations=320)
    # mirrored pairs of draws: what one side of the centre gains the other loses
    assert np.allclose(out.x, 0.5)


def test_a_narrow_coordinate_is_centred_first():
    # wide in five coordinates, 0.1 wide in the first: a layout 0.005 from that face
    d = 6
    oracle = ProductOracle(d, {"hit": OracleEvent((), tuple(range(d)), BoxRegion(
        (0.45,) + (0.1,) * (d - 1), (0.55,) + (0.9,) * (d - 1)))})
    x0 = np.array([0.545, 0.3, 0.7, 0.5, 0.6, 0.4])
    for seed in range(3):
        out = center_layout(x0, oracle.simulate, oracle.validity, np.random.default_rng(seed),
                            simulations=240)
        assert abs(out.x[0] - 0.5) < 0.025  # from 0.045 off the slab's middle


def test_overlapping_layouts_are_never_simulated_nor_returned():
    # an invalid ball (overlapping bodies) sits right beside the way in
    x0 = edge_point(4, 0.02, 0)
    inward = (0.5 - x0) / np.linalg.norm(0.5 - x0)
    blocker = tuple(x0 + 0.1 * inward)
    oracle = ball_oracle(4, invalid=((blocker, 0.06),))
    simulate = Counting(oracle)
    out = center_layout(x0, simulate, oracle.validity, np.random.default_rng(0),
                        simulations=400)
    assert oracle.validity(simulate.layouts).all()
    assert oracle.validity(out.centres).all()
    assert float(oracle.events["hit"].region.signed_distance(out.x[None, :])[0]) > 0.05


def test_a_layout_hemmed_in_on_every_side_ends_the_centring():
    # parts that touch all round: every draw, however close, overlaps; the centring must
    # stop rather than halve its radius for ever
    oracle = ball_oracle(3)
    x0 = np.full(3, 0.5)
    simulate = Counting(oracle)

    def only_x0(P):
        return np.all(np.atleast_2d(P) == x0, axis=1)

    out = center_layout(x0, simulate, only_x0, np.random.default_rng(0), simulations=320)
    assert out.n_simulations == 0 and not simulate.asked and np.array_equal(out.x, x0)
    assert np.isnan(out.hit_rates).all() and out.radii[-1] == 1e-3


def test_less_than_a_batch_of_budget_simulates_nothing():
    oracle = ball_oracle(3)
    simulate = Counting(oracle)
    x0 = edge_point(3, 0.03, 0)
    out = center_layout(x0, simulate, oracle.validity, np.random.default_rng(0),
                        simulations=15, batch=16)
    assert out.n_simulations == 0 and not simulate.asked and np.array_equal(out.x, x0)


# --- in the final choice -----------------------------------------------------------------------


def _choose(settings, x_opt, oracle, simulate=None):
    from test_learning import disc_model

    X = np.atleast_2d(x_opt)
    return verify_layout(disc_model(), x_opt, X, oracle.simulate(X), simulate or oracle.simulate,
                         oracle.validity, settings, rng=np.random.default_rng(0))


def test_the_final_choice_keeps_the_centre_when_it_does_better():
    oracle = ball_oracle(2)
    settings = LearningSettings(verify_samples=32, error_radius=1.0, centering="always",
                                centering_simulations=160)
    simulate = Counting(oracle)
    x_edge = np.array([0.5, 0.79])  # the only candidate, 0.01 inside the edge
    v = _choose(settings, x_edge, oracle, simulate)
    before, centre = v.centering_check
    assert not before.centered and centre.centered and v.chosen is centre
    assert np.array_equal(before.x, x_edge) and v.candidates == ()
    assert centre.source == before.source == "optimum"
    assert centre.success_rate > before.success_rate + 0.05
    assert np.linalg.norm(centre.x - 0.5) < 0.2
    # the optimum's own simulation, the centring, the centre's own simulation, the copies
    assert v.n_simulations == (1 + v.centering.n_simulations + 1
                               + before.n_valid + centre.n_valid) == len(simulate.layouts)
    assert v.n_centering_simulations == v.n_simulations - 1  # all but the optimum's own
    assert before.n_valid + centre.n_valid > 200  # 128 errors each, a few outside


def test_a_centre_that_does_no_better_is_not_kept():
    # a point of the region that is deep already, and a second candidate deeper still: the
    # choice among candidates comes first, then its centre must beat it at the same errors
    oracle = ball_oracle(2)
    settings = LearningSettings(verify_samples=32, error_radius=1.0, centering="always",
                                centering_simulations=64, verify_candidates=2)
    from test_learning import disc_model

    X = np.array([[0.52, 0.47], [0.6, 0.6]])
    labels = oracle.simulate(X)
    for x_opt in (np.array([0.5, 0.5]), np.array([0.52, 0.47])):
        v = verify_layout(disc_model(), x_opt, X, labels, oracle.simulate, oracle.validity,
                          settings, rng=np.random.default_rng(1))
        best = max(v.candidates, key=lambda c: c.success_rate)
        if v.centering_check is None:
            assert v.chosen is best
            continue
        before, centre = v.centering_check
        assert np.array_equal(before.x, best.x)
        if v.chosen.centered:
            assert centre.success_rate > before.success_rate
        else:
            assert v.chosen is best and centre.success_rate <= before.success_rate


@pytest.mark.parametrize(("mode", "found", "centred"), [
    ("off", 3, False), ("auto", None, False), ("auto", 100, False), ("auto", 99, True),
    ("always", 100, True)])
def test_when_the_layout_is_centred(mode, found, centred):
    # by default only when the exploration found fewer successes than it was to collect
    oracle = ball_oracle(2)
    settings = LearningSettings(verify_samples=32, error_radius=1.0, centering=mode,
                                centering_simulations=32, n_successes=100)
    x_edge = np.array([0.5, 0.79])
    from test_learning import disc_model

    v = verify_layout(disc_model(), x_edge, x_edge[None, :], oracle.simulate(x_edge[None, :]),
                      oracle.simulate, oracle.validity, settings,
                      rng=np.random.default_rng(0), exploration_successes=found)
    assert (v.centering is not None) is centred
    if not centred:
        assert v.centering_check is None and v.chosen.source == "optimum"
        assert v.n_simulations == 1


def test_a_run_whose_exploration_fell_short_is_centred(tmp_path):
    # the user's view: `optimize` on a scenario where the exploration ends at its cap with
    # fewer successes than it was to collect; the run says what the centring did
    from _support import TINY

    from rgmcad.runs.workflow import optimize_scenario

    # (stalled after one unchanged batch, so that the record of a stall is seen too)
    short = TINY.replace(n_successes=10_000, exploration_max_iter=2, centering_simulations=32,
                         centering_check_samples=16, exploration_stall_batches=1)
    run = optimize_scenario(SIMPLE, seed=0, settings=short, run_dir=tmp_path / "short",
                            workers=1, hand=None)  # the centring is what is tested
    c = run.summary["centering"]
    assert c is not None and c["simulations"] == 32 and len(c["radii"]) == 2
    assert ("centred by simulation" in run.summary["source"]) is c["kept"]
    by_stage = run.summary["simulations_by_stage"]
    assert by_stage["exploration"] == TINY.n_initial + 2 * 10  # to the cap
    assert by_stage["centering"] >= 32 + 1 and by_stage["verification"] >= 1
    assert sum(by_stage.values()) == run.summary["evaluations"]
    explored = run.summary["exploration"]  # what the run's result says of its exploration
    assert explored["samples"] == by_stage["exploration"] and explored["iterations"] == 2
    assert explored["successes"] < 10_000 and explored["stalled_at"] in (1, 2)
    report = (tmp_path / "short" / "report.md").read_text()
    assert f"exploration: {explored['samples']} samples, {explored['successes']} global" in report
    assert f"stalled after iteration {explored['stalled_at']}" in report
    full = optimize_scenario(SIMPLE, seed=0, settings=TINY.replace(centering_simulations=32),
                             run_dir=tmp_path / "enough", workers=1, hand=None)
    # 60 exploration samples, stopped by N+ (measured: not at the cap of 40 + 8 x 10)
    assert full.summary["simulations_by_stage"]["exploration"] < 120
    assert full.summary["centering"] is None
    assert full.summary["exploration"]["successes"] >= TINY.n_successes
    assert full.summary["exploration"]["stalled_at"] is None
    assert "stalled" not in (tmp_path / "enough" / "report.md").read_text()
    assert "centering" not in full.summary["simulations_by_stage"]


@pytest.mark.parametrize(("changes", "word"), [
    ({"centering_simulations": 100, "verify_samples": 0}, "verify_samples"),
    ({"centering_hit_rate": 1.0}, "centering_hit_rate"),
    ({"centering_batch": 0}, "centering_batch"),
    ({"centering_simulations": -1}, "centering_simulations"),
    ({"centering": "sometimes"}, "centering"),
])
def test_centring_settings_are_checked(changes, word):
    with pytest.raises(ValueError, match=word):
        LearningSettings(**changes)
