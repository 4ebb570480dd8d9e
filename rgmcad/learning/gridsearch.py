"""The SVM training jobs of :class:`~.classifier.SuccessClassifier`: the grid search over C,
gamma and class weights, and single fits. Module-level functions, so that they can be sent to
worker processes.

A hand-written search rather than ``GridSearchCV``: each fold is standardised once instead of
once per setting and accuracies are computed in numpy; the settings that share a gamma share
one RBF kernel matrix per fold, given to libsvm precomputed. Same folds, grid and choice
(first best in grid order); see docs/decisions.md for the measurements.
"""

from __future__ import annotations

import itertools

import numpy as np
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC

from .parallel import parallel_map

__all__ = ["svm", "fit_fold", "grid_search", "score_settings"]


def svm(params) -> SVC:
    return SVC(kernel="rbf", C=float(params["C"]), gamma=float(params["gamma"]),
               class_weight=params["class_weight"], cache_size=512)


def fit_fold(Z, y, train, test, params):
    """Fit scaler and SVM on ``train``; the decision values on ``test``, or the fitted
    pipeline when ``test`` is None."""
    model = Pipeline([("scale", StandardScaler()), ("svm", svm(params))]).fit(Z[train], y[train])
    return model if test is None else model.decision_function(Z[test])


# Largest training part whose RBF kernel the grid search computes in numpy (a float64
# matrix of 72 MB); larger folds let libsvm compute kernel values as it needs them.
PRECOMPUTED_MAX_ROWS = 3000


def score_settings(Z, y, train, test, settings):
    """Accuracy on ``test`` of an SVM fitted on ``train`` for each setting; the fold is
    standardised once.

    Settings that share a gamma share one kernel matrix, computed in numpy and given to
    libsvm as a precomputed kernel (libsvm's own RBF kernel computes every value again for
    each C)."""
    scaler = StandardScaler().fit(Z[train])
    A, B = scaler.transform(Z[train]), scaler.transform(Z[test])
    ytrain, ytest = y[train], y[test]
    if len(train) > PRECOMPUTED_MAX_ROWS:
        return [float(np.mean((svm(p).fit(A, ytrain).decision_function(B) > 0) == ytest))
                for p in settings]
    norms = (A * A).sum(axis=1)
    D_train = np.maximum(norms[:, None] + norms[None, :] - 2.0 * (A @ A.T), 0.0)
    D_test = np.maximum((B * B).sum(axis=1)[:, None] + norms[None, :] - 2.0 * (B @ A.T), 0.0)
    scores = []
    gamma = None  # the jobs group settings by gamma: one pair of matrices at a time
    for p in settings:
        if float(p["gamma"]) != gamma:
            gamma = float(p["gamma"])
            K_train, K_test = np.exp(-gamma * D_train), np.exp(-gamma * D_test)
        fitted = SVC(kernel="precomputed", C=float(p["C"]), class_weight=p["class_weight"],
                     cache_size=512).fit(K_train, ytrain)
        f = K_test[:, fitted.support_] @ fitted.dual_coef_[0] + fitted.intercept_[0]
        scores.append(float(np.mean((f > 0) == ytest)))
    return scores


def grid_search(Z, y, C_grid, gamma_grid, class_weights, folds, n_jobs, halving=1,
                 min_train=100, seed=0):
    """The first setting of the grid (C, then gamma, then class weight) with the best mean
    accuracy over ``folds``, and that accuracy. Work is split by fold and gamma.

    With ``halving`` = eta > 1, successive halving: every setting is scored on the folds
    with each training part cut to a stratified random subset of ``eta**-R`` of its rows,
    the best third (``1 / eta``) of the settings is scored again on ``eta`` times more
    rows, and so on up to the whole training parts, where the choice is made. ``R`` is the
    largest number of rungs such that the smallest subsets keep ``min_train`` rows and each
    rung keeps at least two settings; with ``R = 0`` this is the exhaustive search. The test
    parts are always whole, so every score is an accuracy on the same points."""
    splits = list(folds.split(Z, y))
    grid = [{"C": float(C), "gamma": float(g), "class_weight": w}
            for C, g, w in itertools.product(C_grid, gamma_grid, class_weights)]
    n_train = min(len(train) for train, _ in splits)
    rungs = 0
    if halving > 1:
        while (n_train / halving ** (rungs + 1) >= min_train
               and len(grid) / halving ** (rungs + 1) >= 2):
            rungs += 1
    rs = np.random.RandomState(seed)
    subsets = [stratified_order(y, train, rs) for train, _ in splits]
    alive = np.arange(len(grid))
    for rung in range(rungs + 1):
        share = float(halving) ** (rung - rungs)
        scores = score_grid(Z, y, splits, subsets, share, [grid[i] for i in alive], n_jobs)
        if rung < rungs:  # keep the best 1/eta, ties in grid order
            keep = max(2, int(np.ceil(len(alive) / halving)))
            alive = np.sort(alive[np.argsort(-scores, kind="stable")[:keep]])
    best = int(np.argmax(scores))
    return dict(grid[alive[best]]), float(scores[best])


def stratified_order(y, train, rs):
    """The rows of ``train`` in an order whose every prefix keeps the class proportions
    (each class shuffled, then the two interleaved by rank)."""
    parts = [train[y[train] == c] for c in (False, True)]
    keys = [(np.arange(len(p)) + rs.random_sample(len(p))) / max(len(p), 1) for p in parts]
    rows = np.concatenate([rs.permutation(p) for p in parts])
    return rows[np.argsort(np.concatenate(keys), kind="stable")]


def score_grid(Z, y, splits, subsets, share, settings, n_jobs):
    """(len(settings),) mean accuracy over the folds, each fold trained on the first
    ``share`` of its ordered training rows (at least 2 per class when the fold has them)."""
    by_gamma: dict[float, list[int]] = {}
    for i, p in enumerate(settings):
        by_gamma.setdefault(p["gamma"], []).append(i)
    jobs, where = [], []
    for k, ((_, test), order) in enumerate(zip(splits, subsets, strict=True)):
        train = order[: max(int(round(share * len(order))), 4)]
        if share < 1 and len(np.unique(y[train])) < 2:
            train = order
        for idx in by_gamma.values():
            jobs.append((Z, y, train, test, [settings[i] for i in idx]))
            where.append((k, idx))
    scores = np.zeros((len(splits), len(settings)))
    for (k, idx), acc in zip(where, parallel_map(score_settings, jobs, n_jobs), strict=True):
        scores[k, idx] = acc
    return scores.mean(axis=0)
