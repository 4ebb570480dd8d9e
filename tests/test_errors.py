"""The learner's errors of global robustness measure what `rgmcad evaluate` measures.

The refinement and the final choice average the success over a fixed design of errors
(rgmcad.learning.errors). With ``error_radius = 1`` that average must be rho_g as the
evaluation defines it (balls of every radius up to 1, intersected with the design space),
anywhere in the space: in the middle, against one face, and in a corner, where rejecting the
errors that leave the cube would keep almost none.
"""

from __future__ import annotations

import numpy as np
import pytest

from rgmcad.learning.errors import ball_errors, expected_success, gaussian_errors
from rgmcad.learning.oracles import BallRegion, BoxRegion, OracleEvent, ProductOracle, SlabRegion
from rgmcad.runs.robustness import EPS_GRID, ball_samples


class TrueModel:
    """A model that knows the oracle's success probability."""

    def __init__(self, oracle):
        self.oracle = oracle

    def success_proba(self, X):
        return self.oracle.global_probability(np.atleast_2d(X))


def rho_g_by_evaluation(oracle, x, n=4000, seed=0):
    """rho_g of ``x`` as `rgmcad evaluate` estimates it (uniform ball samples per radius,
    rejected outside the cube; trapezoid over the grid), with many samples."""
    rng = np.random.default_rng(seed)
    rates = [oracle.global_probability(ball_samples(x, max(eps, 1e-9), n, rng)).mean()
             for eps in EPS_GRID]
    return float(np.trapezoid(rates, EPS_GRID))


def oracle_8d():
    # success needs x0 in [0.2, 0.9] and (x1, x2) in a ball: the rate varies with the radius
    return ProductOracle(8, {
        "a": OracleEvent(dims=(0,), region=BoxRegion((0.2,), (0.9,))),
        "b": OracleEvent(parents=("a",), dims=(1, 2), region=BallRegion((0.3, 0.1), 0.45)),
    })


@pytest.mark.parametrize("where", ["middle", "face", "corner", "near corner"])
def test_ball_errors_average_is_rho_g_everywhere(where):
    oracle = oracle_8d()
    x = {"middle": np.full(8, 0.5),
         "face": np.r_[0.5, 0.3, 0.0, np.full(5, 0.5)],
         "corner": np.r_[0.25, 0.0, 0.0, np.zeros(5)],
         "near corner": np.r_[0.3, 0.02, 0.97, 0.01, 0.99, 0.0, 1.0, 0.05]}[where]
    design = ball_errors(8, 1.0, 4096)
    learner = float(expected_success(TrueModel(oracle), x[None, :], design)[0])
    evaluation = rho_g_by_evaluation(oracle, x)
    assert learner == pytest.approx(evaluation, abs=0.02)


def test_ball_errors_rank_a_wide_region_above_a_sharp_point():
    """Two layouts that both succeed: one at the edge of a large success region, one in a
    small isolated one. Point probabilities tie; the errors of global robustness must not."""
    oracle = ProductOracle(4, {"a": OracleEvent(dims=(0, 1), region=BoxRegion((0.0, 0.0),
                                                                               (0.6, 0.6)))})
    wide, sharp = np.r_[0.3, 0.3, 0.5, 0.5], np.r_[0.58, 0.58, 0.5, 0.5]
    p = expected_success(TrueModel(oracle), np.vstack([wide, sharp]), ball_errors(4, 1.0, 1024))
    assert p[0] > p[1] + 0.1
    assert rho_g_by_evaluation(oracle, wide) > rho_g_by_evaluation(oracle, sharp) + 0.1


def test_designs_are_fixed_and_weights_sum_to_one():
    a, b = ball_errors(5, 0.7, 100), ball_errors(5, 0.7, 100)
    assert np.array_equal(a.offsets, b.offsets) and len(a.offsets) == 128
    assert np.linalg.norm(a.offsets, axis=1).max() <= 0.7
    for x in (np.zeros(5), np.full(5, 0.5), np.r_[1.0, 0.0, 0.3, 1.0, 0.9]):
        offsets, raw = a.at(x)
        w = a.normalized(raw)
        assert w.sum() == pytest.approx(1.0)
        assert np.all((x + offsets[w > 0] >= 0) & (x + offsets[w > 0] <= 1))
    g = gaussian_errors(5, 0.05, 30)
    assert np.allclose(g.offsets.std(axis=0), 0.05) and np.allclose(g.offsets.mean(axis=0), 0)


def two_regions():
    """Success through either of two alternatives over (x0, x1): a band across the whole
    square, 0.2 wide, or a disc of radius 0.13 away from it; x2 and x3 do not matter. Under
    small Gaussian errors (0.05) the disc's centre is the safer point (0.97 against 0.95);
    under the errors of global robustness the band's is (0.47 against 0.37)."""
    return ProductOracle(4, {
        "wide": OracleEvent(dims=(0, 1), region=SlabRegion((1.0, 1.0), 0.6 / np.sqrt(2), 0.1)),
        "sharp": OracleEvent(dims=(0, 1), region=BallRegion((0.83, 0.83), 0.13)),
        "end": OracleEvent(parents=("wide", "sharp"), join="any"),
    })


@pytest.mark.parametrize("seed", [0, 1])
def test_optimising_for_global_robustness_lands_in_the_wide_region(seed):
    """What a user of `optimize` gets: the layout whose neighbourhood works, not merely a
    point that works. Both regions are certain at their centres; only the wide one survives
    large errors, and rho_g (as evaluate measures it) says so."""
    from rgmcad.learning import LearningSettings, learn_and_optimize, verify_layout

    oracle = two_regions()
    settings = LearningSettings(
        n_initial=96, n_successes=24, exploration_batch=8, active_batch=8, active_max_iter=2,
        svm_C_grid=(1.0, 10.0, 100.0), svm_gamma_grid=(1.0, 10.0), svm_class_weights=(None,),
        error_radius=1.0, placement_samples=128, verify_samples=64,
        centering_simulations=0)
    result = learn_and_optimize(oracle, settings, seed)
    chosen = verify_layout(result.model, result.x, result.X, result.labels, oracle.simulate,
                           oracle.validity, settings).chosen.x
    assert oracle.events["wide"].region.contains(chosen[None, :2])[0]
    assert rho_g_by_evaluation(oracle, chosen, n=1000) > rho_g_by_evaluation(
        oracle, np.r_[0.83, 0.83, chosen[2:]], n=1000) + 0.05


def test_interleaved_ball_design_spreads_every_prefix_over_the_radii():
    # the final choice simulates a ball design's first 32, 64, 128 errors before the rest:
    # each such prefix must hold every radius equally, and the whole is the same design
    design = ball_errors(5, 1.0, 256)
    raced = design.interleaved()
    for n in (32, 64, 128, 256):
        assert np.bincount(raced.levels[:n], minlength=8).tolist() == [n // 8] * 8
    assert sorted(map(tuple, raced.offsets)) == sorted(map(tuple, design.offsets))
    # and the offsets of one radius keep their order (a prefix is the block's prefix)
    for level in range(8):
        np.testing.assert_array_equal(raced.offsets[raced.levels == level],
                                      design.offsets[design.levels == level])
    gaussian = gaussian_errors(5, 0.05, 64)
    assert gaussian.interleaved() is gaussian
