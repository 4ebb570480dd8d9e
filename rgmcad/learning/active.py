"""Active learning by query synthesis around the support vectors (paper Alg. 2, authors'
``learn_active`` with ``_get_support_distrib``, SPEC section 5.3).

At each iteration the query distribution is a mixture with one Gaussian per support vector
``v_i`` of the current SVM: weight ``|f(v_i)|``, covariance
``query_variance_scale * |f(v_i)| * diag(1 / s)`` with ``s`` the per-feature standard
deviation of the training data (the paper's "U, inverse of the standardisation scaling"; a
*covariance*, as in the authors' code). Coordinates outside the model's subspace get
variance 0, so a conditional model's queries keep the support vector's other coordinates,
where the event's parents succeeded. ``10 * active_batch`` valid candidates are drawn and
the ``active_batch`` closest to the boundary (smallest ``|f|``) are simulated.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from .classifier import SuccessClassifier
from .sampling import first_valid, sample_mixture
from .settings import LearningSettings

__all__ = ["ActiveLearningResult", "query_distribution", "synthesize_queries", "learn_active"]

logger = logging.getLogger(__name__)

LabelFn = Callable[[np.ndarray], Sequence[bool | None]]
ValidityFn = Callable[[np.ndarray], np.ndarray]
AcceptFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ActiveLearningResult:
    """Result of :func:`learn_active`.

    Attributes
    ----------
    classifier : SuccessClassifier
        Final, calibrated model (trained on ``X, y``).
    X : (n, d) float
        Training data at the end: the initial data plus the labelled queries.
    y : (n,) bool
    queries : (m, d) float
        Every simulated query, labelled or not, in order.
    n_labelled : int
        Queries that returned a label (the rest came back None and were discarded).
    accuracy_history : tuple of float
        Cross-validated accuracy after each fit (initial fit first).
    """

    classifier: SuccessClassifier
    X: np.ndarray
    y: np.ndarray
    queries: np.ndarray
    n_labelled: int
    accuracy_history: tuple[float, ...]

    @property
    def n_queries(self) -> int:
        """Simulations run by active learning."""
        return len(self.queries)


def query_distribution(
    classifier: SuccessClassifier, X_train: np.ndarray, variance_scale: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mixture of Gaussians around the support vectors of a fitted classifier.

    Parameters
    ----------
    classifier : SuccessClassifier
        Fitted, not constant.
    X_train : (n, d) float
        The data it was fitted on (full design vectors), to recover the support vectors'
        full coordinates.
    variance_scale : float
        Factor on the covariance.

    Returns
    -------
    means : (v, d) float
    weights : (v,) float
        Proportional to ``|f(v_i)|`` (uniform if all are 0).
    variances : (v, d) float
        ``variance_scale * |f(v_i)| / s_j`` on the classifier's columns, 0 elsewhere.
    """
    means = np.asarray(X_train, dtype=float)[classifier.support_]
    f = np.abs(classifier.decision_function(means))
    weights = f if f.sum() > 0 else np.ones_like(f)
    variances = np.zeros_like(means)
    variances[:, classifier.dims_] = (
        variance_scale * f[:, None] / classifier.feature_std_[None, :]
    )
    return means, weights, variances


def synthesize_queries(
    classifier: SuccessClassifier,
    X_train: np.ndarray,
    validity: ValidityFn,
    n_queries: int,
    settings: LearningSettings,
    rng: np.random.Generator,
    *,
    accept: AcceptFn | None = None,
) -> tuple[np.ndarray, int]:
    """Pick ``n_queries`` valid design vectors near the current decision boundary.

    Draws ``max_draws_factor * 10 * n_queries`` candidates from :func:`query_distribution`,
    drops those ``accept`` rejects (if it rejects all, it is ignored), tests validity in
    order until ``10 * n_queries`` are valid, and returns the ``n_queries`` of smallest
    ``|f|`` (ties in draw order).

    Returns
    -------
    queries : (<= n_queries, d) float
    n_validity_tests : int
    """
    n_pool = 10 * n_queries
    means, weights, variances = query_distribution(
        classifier, X_train, settings.query_variance_scale
    )
    cands = sample_mixture(means, weights, variances, settings.max_draws_factor * n_pool, rng)
    pool = None
    if accept is not None:
        pool, n_tested = _first_valid_accepted(cands, accept, validity, n_pool, 10 * n_pool)
        if pool is None:
            logger.info("active learning: no candidate passed the parent filter; ignoring it")
    if pool is None:
        pool, n_tested = first_valid(cands, validity, n_pool)
    if len(pool) == 0:
        return pool, n_tested
    score = np.abs(classifier.decision_function(pool))
    keep = np.argsort(score, kind="stable")[:n_queries]
    return pool[np.sort(keep)], n_tested


def _first_valid_accepted(cands, accept, validity, n, chunk):
    """:func:`first_valid` over the rows ``accept`` keeps, the filter applied ``chunk`` rows
    at a time and only as far as needed (the same rows as filtering everything first);
    ``(None, 0)`` when it keeps no row at all."""
    kept, n_kept, n_tested, any_kept = [], 0, 0, False
    for start in range(0, len(cands), chunk):
        block = cands[start : start + chunk]
        block = block[np.asarray(accept(block), dtype=bool)]
        if len(block) == 0:
            continue
        any_kept = True
        rows, tested = first_valid(block, validity, n - n_kept)
        kept.append(rows)
        n_kept += len(rows)
        n_tested += tested
        if n_kept >= n:
            break
    if not any_kept:
        return None, 0
    return np.vstack(kept), n_tested


def learn_active(
    X: np.ndarray,
    y: Sequence[bool],
    label: LabelFn,
    validity: ValidityFn,
    settings: LearningSettings,
    rng: np.random.Generator,
    *,
    dims: Sequence[int] | None = None,
    accept: AcceptFn | None = None,
) -> ActiveLearningResult:
    """Train a classifier, then alternate query synthesis and retraining (paper Alg. 2).

    Stops when the cross-validated accuracy reaches ``settings.accuracy_target`` or after
    ``settings.active_max_iter`` iterations (the paper prints the loop test inverted; this is
    the code's and the text's meaning). The hyper-parameters are grid-searched on the
    initial data, and again only once the data has grown by more than
    ``settings.search_growth`` since the last search; other refits keep them and cost
    ``calibration_folds + 1`` SVM fits (the out-of-fold values give both the accuracy and
    Platt's calibration) instead of the search's hundreds. The authors searched at every
    iteration and once more at the end. The last fit is the final calibrated model.

    Parameters
    ----------
    X : (n, d) float
        Initial labelled design vectors.
    y : (n,) bool
        Their labels.
    label : callable
        ``label(Q) -> sequence of bool | None``: simulates the queries ``Q`` (m, d); None
        means no label (e.g. the event's parents failed) and the query is discarded.
    validity : callable
        ``validity(X) -> (k,) bool``.
    settings : LearningSettings
    rng : numpy.random.Generator
        Source of the queries and of the classifiers' fold seeds.
    dims : sequence of int, optional
        Subspace of a conditional model; queries vary only these coordinates.
    accept : callable, optional
        ``accept(C) -> (k,) bool``: filter on candidate queries (e.g. "the parents are
        likely to succeed").

    Returns
    -------
    ActiveLearningResult
    """
    X = np.asarray(X, dtype=float)
    y = np.asarray(y, dtype=bool)
    d = X.shape[1]

    def fit(Xf, yf, params=None):
        seed = int(rng.integers(2**31 - 1))
        return SuccessClassifier.from_settings(
            settings, dims=dims, random_state=seed, params=params
        ).fit(Xf, yf)

    clf = fit(X, y)
    searched_at = len(y)
    history = [clf.cv_accuracy_]
    queries: list[np.ndarray] = []
    n_labelled = 0
    k = 0
    while k < settings.active_max_iter and clf.cv_accuracy_ < settings.accuracy_target:
        k += 1
        if clf.is_constant:
            logger.info("active learning: one-class data (%d samples), nothing to refine", len(y))
            break
        Q, _ = synthesize_queries(
            clf, X, validity, settings.active_batch, settings, rng, accept=accept
        )
        if len(Q) == 0:
            logger.warning("active learning iteration %d: no valid query", k)
            break
        out = list(label(Q))
        if len(out) != len(Q):
            raise ValueError(f"label() returned {len(out)} labels for {len(Q)} queries")
        queries.append(Q)
        got = np.array([v is not None for v in out])
        n_labelled += int(got.sum())
        if got.any():
            X = np.vstack([X, Q[got]])
            y = np.concatenate([y, np.array([bool(v) for v in out if v is not None])])
            grown = len(y) > (1.0 + settings.search_growth) * searched_at
            clf = fit(X, y, None if grown or not clf.best_params_ else clf.best_params_)
            searched_at = len(y) if grown else searched_at
        history.append(clf.cv_accuracy_)
        logger.debug(
            "active learning iteration %d: %d/%d labelled, accuracy %.3f",
            k, int(got.sum()), len(Q), clf.cv_accuracy_,
        )
    Qall = np.vstack(queries) if queries else np.empty((0, d))
    return ActiveLearningResult(clf, X, y, Qall, n_labelled, tuple(history))
