"""Which design parameters an event depends on (paper section 6.1): per event, a test for
quasi-determinism and a selection of the dimensions that carry information about its outcome,
by k-NN mutual information against a permutation null.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import digamma
from sklearn.feature_selection import mutual_info_classif

from .parallel import parallel_map
from .settings import LearningSettings

__all__ = ["EventAnalysis", "analyse_event", "joint_mutual_information", "select_dimensions"]

logger = logging.getLogger(__name__)


def joint_mutual_information(Z: np.ndarray, y: np.ndarray, n_neighbors: int = 3) -> float:
    """k-NN estimate (nats) of the mutual information between continuous features ``Z``
    (n, k) and a discrete label ``y`` (n,) (Ross 2014, the estimator scikit-learn applies
    to one feature at a time, here on all columns jointly, max-norm):
    ``psi(n) + psi(k) - <psi(n_y)> - <psi(m_i)>``, where ``m_i`` counts the samples closer
    to sample ``i`` than its k-th neighbour of the same class. Columns should be on
    comparable scales and free of ties (see :func:`select_dimensions`). Clipped at 0.

    ``m_i`` is counted per class: the same-class samples that close are among the k + 1
    the neighbour query returns, so only the other classes need a radius query (half the
    time of one radius query over all samples, same counts).
    """
    Z = np.asarray(Z, dtype=float).reshape(len(y), -1)
    y = np.asarray(y)
    n = len(y)
    radius = np.zeros(n)
    class_size = np.empty(n)
    counts = np.ones(n, dtype=np.int64)  # a lone sample counts itself (it is dropped below)
    members = {c: y == c for c in np.unique(y)}
    trees = {c: cKDTree(Z[m]) for c, m in members.items()}
    for c, m in members.items():
        size = int(m.sum())
        class_size[m] = size
        if size < 2:  # no neighbour of its class (sklearn drops such samples)
            continue
        k = min(n_neighbors, size - 1)
        dist, _ = trees[c].query(Z[m], k=k + 1, p=np.inf)  # itself first
        radius[m] = np.nextafter(dist[:, -1], 0.0)
        counts[m] = np.sum(dist <= radius[m][:, None], axis=1)
    for c, m in members.items():
        if class_size[m][0] < 2:
            continue
        for other, tree in trees.items():
            if other != c:
                counts[m] += tree.query_ball_point(Z[m], radius[m], p=np.inf,
                                                   return_length=True)
    keep = class_size > 1
    if not keep.any():
        return 0.0
    k = min(n_neighbors, int(class_size[keep].min()) - 1)
    mi = (digamma(keep.sum()) + digamma(k) - np.mean(digamma(class_size[keep]))
          - np.mean(digamma(counts[keep])))
    return max(0.0, float(mi))


def select_dimensions(
    X: np.ndarray, y: np.ndarray, settings: LearningSettings, random_state: int
) -> tuple[tuple[int, ...], np.ndarray, float]:
    """Dimensions that carry information about the binary label ``y``.

    ``settings.mi_selection == "forward"`` (default): greedy forward selection on the
    *joint* mutual information. Starting from no dimension, add the ``j`` that maximises
    ``I(y; x_S, x_j)`` while its gain over ``I(y; x_S)`` beats chance: the largest gain any
    remaining dimension reaches with its column permuted (``mi_null_permutations`` times;
    the permutation keeps its distribution and breaks its link to ``y`` and ``x_S``).
    Unlike the per-dimension rule, this finds parameters that matter only jointly with
    another (the landing point of a ball depends on the track's height *given* its x).
    When no single dimension passes although all of them together carry information (a
    permutation test of the label against all columns at the 5 % level), every dimension
    is kept, so that an event decided only by its dimensions together still gets a model
    (see docs/decisions.md, "Event dimensions: joint selection against a permutation floor").

    ``"marginal"``: the authors' rule, ``MI_j > mi_relative_threshold * max(MI)`` on each
    dimension alone, and ``MI_j`` above the largest MI of any dimension against the label
    permuted ``mi_null_permutations`` times.

    Features are scaled to unit standard deviation with a tiny seeded jitter (ties would
    break the k-NN estimator), as scikit-learn does; permutations and jitter are seeded by
    ``random_state``.

    Returns
    -------
    dims : tuple of int
        Possibly empty, ascending.
    mi : (d,) float
        Each dimension's own mutual information with ``y`` (nats).
    floor : float
        The chance level of the last test (0 without permutations).
    """
    y = np.asarray(y, dtype=bool)
    d = X.shape[1]
    if len(y) < 2 or y.all() or not y.any():
        return (), np.zeros(d), 0.0
    rng = np.random.default_rng(random_state)
    if settings.mi_selection == "marginal":
        return _select_marginal(X, y, settings, random_state, rng)

    std = X.std(axis=0)
    Z = X / np.where(std > 0, std, 1.0)
    Z = Z + 1e-10 * np.maximum(1.0, np.abs(Z).mean(axis=0)) * rng.standard_normal(Z.shape)
    k = settings.mi_neighbors

    def mi_of(columns_list):
        """Joint MI of each column set with ``y`` (see :mod:`rgmcad.learning.parallel`)."""
        return parallel_map(joint_mutual_information, [(c, y, k) for c in columns_list],
                            settings.n_jobs)

    selected: list[int] = []
    current = 0.0
    single = np.zeros(d)
    floor = 0.0
    while len(selected) < d:
        rest = [j for j in range(d) if j not in selected]
        base = Z[:, selected]
        candidates = [np.column_stack([base, Z[:, j]]) for j in rest]
        nulls = [np.column_stack([base, rng.permutation(Z[:, j])])
                 for _ in range(settings.mi_null_permutations) for j in rest]
        values = mi_of(candidates + nulls)
        scores = np.array(values[: len(rest)])
        if not selected:
            single[rest] = scores
        best = int(np.argmax(scores))
        floor = max([0.0] + [v - current for v in values[len(rest):]])
        if scores[best] - current <= floor:  # floor >= 0, so a gain is required
            break
        selected.append(rest[best])
        current = float(scores[best])
    if not selected and settings.mi_null_permutations:
        # No parameter is informative alone, yet all of them may be together (a label set
        # by x AND z): a permutation test of the label against every dimension at once, at
        # the 5 % level (it must beat 19 permuted labels; cheap, one estimate each).
        k_all = joint_mutual_information(Z, y, k)
        floor = max(joint_mutual_information(Z, rng.permutation(y), k)
                    for _ in range(max(19, settings.mi_null_permutations)))
        if k_all > floor:
            selected = list(range(d))
    return tuple(sorted(selected)), single, floor


def _select_marginal(X, y, settings, random_state, rng):
    """The authors' per-dimension rule (see :func:`select_dimensions`)."""

    def mi_of(labels, seed):
        return mutual_info_classif(
            X, labels, discrete_features=False, n_neighbors=settings.mi_neighbors,
            random_state=seed,
        )

    mi = mi_of(y, random_state)
    floor = 0.0
    for k in range(settings.mi_null_permutations):
        floor = max(floor, float(mi_of(rng.permutation(y), random_state + k + 1).max()))
    keep = (mi > settings.mi_relative_threshold * float(mi.max())) & (mi > floor)
    return tuple(int(j) for j in np.flatnonzero(keep)), mi, floor


@dataclass(frozen=True)
class EventAnalysis:
    """What the exploration data say about one event.

    Attributes
    ----------
    event : str
    n_samples : int
        Exploration samples on which the event is defined.
    success_rate : float
        Their success fraction (nan without samples).
    quasi_deterministic : bool
    mutual_information : (d,) float or None
        Per-dimension MI estimates (None when not computed).
    mi_floor : float
        Chance level of the MI (see :func:`select_dimensions`).
    dims : tuple of int
        Selected subspace (empty for quasi-deterministic or uninformative events).
    """

    event: str
    n_samples: int
    success_rate: float
    quasi_deterministic: bool
    mutual_information: np.ndarray | None
    dims: tuple[int, ...]
    mi_floor: float = 0.0


def analyse_event(
    X: np.ndarray, y: np.ndarray, event: str, settings: LearningSettings, random_state: int
) -> EventAnalysis:
    """Quasi-determinism test and dimension selection for one event's data."""
    n = len(y)
    if n == 0:
        return EventAnalysis(event, 0, float("nan"), False, None, ())
    rate = float(np.mean(y))
    if rate >= settings.quasi_deterministic_rate:
        return EventAnalysis(event, n, rate, True, None, ())
    dims, mi, floor = select_dimensions(X, y, settings, random_state)
    return EventAnalysis(event, n, rate, False, mi, dims, floor)
