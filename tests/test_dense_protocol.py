"""The authors' dense-set robustness estimate (rgmcad.runs.dense) on synthetic oracles whose
neighbourhoods are known, against our per-radius estimate (rgmcad.runs.robustness)."""

import numpy as np

from rgmcad.runs.dense import dense_curve, dense_valid_set, local_points
from rgmcad.runs.problem import SimRecord
from rgmcad.runs.robustness import ETA, local_robustness
from rgmcad.sim.run import Outcome


def _records(success):
    return [SimRecord(True, Outcome.SUCCESS if s else Outcome.FAILURE, {}, 0.0) for s in success]


def _dense(x, oracle, validity, d, n, seed):
    X = dense_valid_set(validity, d, n, seed)
    L = np.vstack([x, local_points(x, 100, np.random.default_rng(seed))])
    L = L[validity(L)]
    return dense_curve(x, X, oracle(X), L, oracle(L), rng=seed)


def test_dense_estimate_matches_ours_where_the_neighbourhood_is_known():
    # success below the plane y0 + y1 = 1, x 0.28 away from it; a tenth of the space invalid.
    # The 101 local points count in every ball (the authors appended them to the dense set),
    # which lifts the dense rho_g by about 0.007 here: within its sampling error in 4-D
    def oracle(X):
        return X[:, 0] + X[:, 1] < 1

    def validity(X):
        return np.atleast_2d(X)[:, 3] < 0.9

    x = np.array([0.3, 0.3, 0.5, 0.4])
    dense = _dense(x, oracle, validity, 4, 4096, seed=1)
    ours = local_robustness(x, validity, lambda X: _records(oracle(X)), 100, 2)
    reference = local_robustness(x, validity, lambda X: _records(oracle(X)), 4000, 3,
                                 candidate_factor=2)
    se_dense = (dense.rho_g_high - dense.rho_g_low) / (2 * 1.96)
    se_ours = (ours.rho_g_high - ours.rho_g_low) / (2 * 1.96)
    assert 0.002 < se_dense < 0.05
    assert abs(dense.rho_g - reference.rho_g) < 3 * se_dense
    assert abs(dense.rho_g - ours.rho_g) < 3 * np.hypot(se_dense, se_ours)
    assert np.all(dense.rho[dense.eps < 0.25] == 1)  # inside the success region
    assert dense.rho[-1] < 0.9


def test_small_balls_rest_on_the_local_points():
    # in 8-D the success region is a ball of radius 0.05 about x: the true rho_l falls like
    # (0.05 / eps)^8, ours sees that; 4096 Sobol points put none within 0.2 of x, so the
    # dense curve stays at the local points' rate (1) there
    x = np.full(8, 0.5)

    def oracle(X):
        return np.linalg.norm(X - x, axis=1) < 0.05

    def everywhere(X):
        return np.ones(len(np.atleast_2d(X)), dtype=bool)

    dense = _dense(x, oracle, everywhere, 8, 4096, seed=4)
    ours = local_robustness(x, everywhere, lambda X: _records(oracle(X)), 50, 5)
    small = (dense.eps > 0.05) & (dense.eps < 0.2)
    assert np.all(dense.rho[small] == 1) and np.all(dense.counts[small] == 101)
    assert np.all(ours.rho[small & (ours.eps > 0.1)] < 0.1)
    assert dense.rho_g > ours.rho_g + 0.1


def test_dense_set_is_valid_reproducible_and_nested():
    def validity(X):
        return np.atleast_2d(X)[:, 0] > 0.6

    big = dense_valid_set(validity, 3, 1000, seed=7, block=256)
    assert big.shape == (1000, 3) and validity(big).all()
    np.testing.assert_array_equal(dense_valid_set(validity, 3, 300, seed=7, block=256),
                                  big[:300])
    assert not np.array_equal(dense_valid_set(validity, 3, 300, seed=8, block=256), big[:300])
    corner = np.zeros(3)
    L = local_points(corner, 500, np.random.default_rng(0))
    assert L.min() >= 0 and L.max() <= ETA and L.min(axis=0).max() < ETA / 50
