"""The success classifier: a cross-validated RBF SVM with Platt-calibrated probabilities and
their analytic gradient (paper sections 5.2-5.3, authors' ``train_svc``).

Pipeline: optional column subset (the event's subspace) -> ``StandardScaler`` -> ``SVC(rbf)``,
with C, gamma and the class weighting chosen by a stratified-k-fold grid search (or given,
see ``params``). The probability is Platt's sigmoid ``p = 1 / (1 + exp(a f(x) + b))`` of the
decision function ``f``, fitted on out-of-fold decision values of ``calibration_folds``
folds; the same out-of-fold values give the model's accuracy. Then one SVM is fitted on all
the data.

Why this calibration rather than ``SVC(probability=True)`` (libsvm's internal Platt scaling,
which the authors used): both fit Platt's sigmoid on 5-fold out-of-fold decision values, and
measured on a noisy 2-D disc oracle (5 seeds, 200 and 600 training points, three noise
models) the out-of-fold variant here (then scikit-learn's ``CalibratedClassifierCV(
method="sigmoid", ensemble=False)``, the same computation) was as good or slightly better:
mean squared error to the true probability 0.0036 vs 0.0038 (600 points, logistic
boundary), 0.0107 vs 0.0111 (200 points). It also makes ``predict`` and ``predict_proba``
come from one model (libsvm's probabilities come from a separate internal model and can
disagree with ``predict``), its folds are stratified and seeded from ``random_state``, and
``SVC(probability=True)`` is deprecated since scikit-learn 1.9. An averaged ensemble of the
fold models was worse (0.0139 at 200 points) and would need k SVMs per gradient.

Why a hand-written grid search rather than ``GridSearchCV``: each fold is standardised once
instead of once per setting and the accuracy is computed in numpy, which removes the
per-fit overhead of pipelines, scorers and input validation (about 4 ms, most of the cost
on small data: 294 fits on 113 samples took 1.4 s, now 0.5 s); folds, grid and the choice
(first best in grid order) are the same. The settings that share a gamma share one RBF
kernel matrix per fold, computed in numpy and given to libsvm precomputed (2.3 times less CPU
on BALLRUN's searches, same accuracies; see ``_score_settings``). Optionally
(``search_halving``) the search is a successive halving: the settings are ranked on
stratified subsets of the training folds and only the best third goes on to more rows (see
``LearningSettings.search_halving`` for its measurements and why it is not the default).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.optimize import minimize
from scipy.special import expit, log_expit
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.model_selection import StratifiedKFold
from sklearn.pipeline import Pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC
from sklearn.utils import check_random_state
from sklearn.utils.validation import check_array, check_is_fitted

from .parallel import parallel_map
from .settings import LearningSettings

__all__ = ["SuccessClassifier"]

_LOG_GRID = tuple(float(v) for v in np.logspace(-3, 3, 7))


class SuccessClassifier(ClassifierMixin, BaseEstimator):
    """Probability of success of a design vector, learnt from simulated labels.

    Parameters
    ----------
    dims : sequence of int, optional
        Columns the model sees (an event's subspace); None = all. ``fit`` and the
        predictions always take full design vectors (n, d); gradients are (n, d) with zeros
        outside ``dims``.
    C_grid, gamma_grid : tuple of float
        Grid-searched SVM regularisation and RBF width (gamma for standardised features).
    class_weights : tuple of {None, "balanced"}
        Class weightings tried by the grid search.
    cv_folds : int
        Stratified shuffled folds of the grid search.
    calibration_folds : int
        Stratified shuffled folds of the out-of-fold decision values for Platt scaling.
    search_halving : int
        Successive halving factor of the grid search (1 = exhaustive); see
        ``LearningSettings.search_halving``.
    search_min_train : int
        Fewest training rows per fold in the first rung of the halving.
    n_jobs : int, optional
        Processes of the grid search and of the calibration folds (joblib), unless
        :func:`rgmcad.learning.parallel.jobs_on` lends an executor; the result does not
        depend on it.
    params : dict, optional
        Fixed ``C``, ``gamma`` and ``class_weight``: no grid search (active learning
        refits with the hyper-parameters its first fit chose).
    random_state : int, numpy.random.RandomState or None
        Seeds the fold shuffling (the only randomness; the SVM is deterministic).

    Attributes
    ----------
    dims_ : (k,) int
        Columns used.
    n_features_in_ : int
        d.
    classes_ : (2,) bool
        ``[False, True]``, always, so that ``predict_proba(X)[:, 1]`` is P(success).
    constant_ : float or None
        Set when the training data has fewer than two samples of a class (the one-class
        case): the probability is then this constant, the Laplace estimate
        ``(n_success + 1) / (n + 2)``, and every gradient is 0.
    cv_accuracy_ : float
        Accuracy of the out-of-fold predictions of the ``calibration_folds`` folds at the
        chosen hyper-parameters (the paper's "acc"; unlike the grid search's best score it
        is not biased upward by the choice); the majority-class rate in the one-class case.
    search_accuracy_ : float or None
        Best mean accuracy of the grid search (None when ``params`` was given).
    best_params_ : dict
        Chosen (or given) ``C``, ``gamma`` and ``class_weight``.
    pipeline_ : sklearn.pipeline.Pipeline
        Scaler and SVM refitted on all training data.
    platt_ : (float, float)
        Platt's ``(a, b)``.
    support_ : (v,) int
        Indices of the support vectors in the training data.
    feature_std_ : (k,) float
        Standard deviation of each used column in the training data (the scaler's ``scale_``;
        1 for a constant column).
    """

    def __init__(
        self,
        dims=None,
        C_grid=_LOG_GRID,
        gamma_grid=_LOG_GRID,
        class_weights=(None,),
        cv_folds=3,
        calibration_folds=5,
        search_halving=1,
        search_min_train=100,
        n_jobs=None,
        params=None,
        random_state=None,
    ):
        self.dims = dims
        self.C_grid = C_grid
        self.gamma_grid = gamma_grid
        self.class_weights = class_weights
        self.cv_folds = cv_folds
        self.calibration_folds = calibration_folds
        self.search_halving = search_halving
        self.search_min_train = search_min_train
        self.n_jobs = n_jobs
        self.params = params
        self.random_state = random_state

    @classmethod
    def from_settings(
        cls, settings: LearningSettings, dims=None, random_state=None, params=None
    ) -> SuccessClassifier:
        """An unfitted classifier with the grid and folds of ``settings`` (and fixed
        hyper-parameters ``params``, if given)."""
        return cls(
            dims=None if dims is None else tuple(int(j) for j in dims),
            C_grid=tuple(settings.svm_C_grid),
            gamma_grid=tuple(settings.svm_gamma_grid),
            class_weights=tuple(settings.svm_class_weights),
            cv_folds=settings.cv_folds,
            calibration_folds=settings.calibration_folds,
            search_halving=settings.search_halving,
            search_min_train=settings.search_min_train,
            n_jobs=settings.n_jobs,
            params=None if params is None else dict(params),
            random_state=random_state,
        )

    # --- fitting -----------------------------------------------------------------------------

    def fit(self, X, y):
        """Grid-search the SVM on ``(X, y)`` (unless ``params`` fixes it), calibrate it on
        out-of-fold decision values, refit it on all data.

        Parameters
        ----------
        X : (n, d) float
            Full design vectors.
        y : (n,) bool
            True = success.

        Returns
        -------
        self
        """
        X = check_array(X, dtype=float)
        y = np.asarray(y).astype(bool).reshape(-1)
        if len(y) != len(X):
            raise ValueError(f"X has {len(X)} rows but y has {len(y)}")
        self.n_features_in_ = X.shape[1]
        self.dims_ = (
            np.arange(X.shape[1]) if self.dims is None else np.asarray(self.dims, dtype=int)
        )
        if self.dims_.size == 0 or np.any((self.dims_ < 0) | (self.dims_ >= X.shape[1])):
            raise ValueError(f"dims {self.dims!r} must be non-empty and within 0..{X.shape[1] - 1}")
        self.classes_ = np.array([False, True])
        Z = X[:, self.dims_]
        n_pos = int(y.sum())
        n_neg = len(y) - n_pos
        self.n_train_ = len(y)
        std = Z.std(axis=0) if len(Z) else np.ones(len(self.dims_))
        self.feature_std_ = np.where(std > 0, std, 1.0)  # as StandardScaler does
        rs = check_random_state(self.random_state)
        seed_cv, seed_cal, seed_halving = (int(v) for v in rs.randint(0, 2**31 - 1, size=3))

        if min(n_pos, n_neg) < 2:
            self.constant_ = (n_pos + 1.0) / (len(y) + 2.0)
            self.cv_accuracy_ = max(n_pos, n_neg) / len(y) if len(y) else 0.0
            self.best_params_ = {}
            self.search_accuracy_ = None
            self.pipeline_ = None
            self.platt_ = (0.0, 0.0)
            self.support_ = np.empty(0, dtype=int)
            return self

        self.constant_ = None
        min_class = min(n_pos, n_neg)
        if self.params is None:
            folds = StratifiedKFold(min(self.cv_folds, min_class), shuffle=True,
                                    random_state=seed_cv)
            self.best_params_, self.search_accuracy_ = _grid_search(
                Z, y, self.C_grid, self.gamma_grid, self.class_weights, folds, self.n_jobs,
                self.search_halving, self.search_min_train, seed_halving,
            )
        else:
            self.best_params_ = {k: self.params[k] for k in ("C", "gamma", "class_weight")}
            self.search_accuracy_ = None

        folds = StratifiedKFold(min(self.calibration_folds, min_class), shuffle=True,
                                random_state=seed_cal)
        jobs = [(Z, y, train, test, self.best_params_) for train, test in folds.split(Z, y)]
        jobs.append((Z, y, np.arange(len(y)), None, self.best_params_))
        *parts, self.pipeline_ = parallel_map(_fit_fold, jobs, self.n_jobs)
        f_oof = np.empty(len(y))
        for (_, _, _, test, _), f in zip(jobs, parts, strict=False):
            f_oof[test] = f
        self.cv_accuracy_ = float(np.mean((f_oof > 0) == y))
        self.platt_ = _platt(f_oof, y)
        self.support_ = np.asarray(self.pipeline_.named_steps["svm"].support_, dtype=int)
        self.feature_std_ = np.asarray(self.pipeline_.named_steps["scale"].scale_, dtype=float)
        return self

    # --- predictions ---------------------------------------------------------------------------

    def _check(self, X) -> np.ndarray:
        check_is_fitted(self, "classes_")
        # not check_array: its validation was 0.8 s of a BALLRUN run (3000 small calls)
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.ndim != 2 or not np.isfinite(X).all():
            raise ValueError("X must be a finite (n, d) array")
        if X.shape[1] != self.n_features_in_:
            raise ValueError(
                f"X has {X.shape[1]} columns, the classifier was fitted on {self.n_features_in_}"
            )
        return X

    @property
    def is_constant(self) -> bool:
        """True in the one-class case (constant probability, zero gradient)."""
        check_is_fitted(self, "classes_")
        return self.constant_ is not None

    def decision_function(self, X) -> np.ndarray:
        """(n,) SVM decision value, > 0 on the success side (the logit of ``constant_`` in
        the one-class case)."""
        X = self._check(X)
        if self.constant_ is not None:
            c = self.constant_
            return np.full(len(X), np.log(c / (1 - c)))
        return self._decision(X, gradient=False)[0]

    def _decision(self, X: np.ndarray, gradient: bool) -> tuple[np.ndarray, np.ndarray | None]:
        """Decision values (n,) and optionally their gradient (n, d), computed in numpy
        from the fitted scaler and SVM (the same numbers as ``pipeline_.decision_function``
        without scikit-learn's per-call validation, which dominates in the optimiser).

        With ``z = (x[dims] - mean) / s`` and ``f(z) = sum_i c_i exp(-gamma |z - v_i|^2) + b``
        over the support vectors ``v_i``: ``df/dz = -2 gamma sum_i c_i K_i (z - v_i)`` and
        ``df/dx_j = (df/dz_j) / s_j`` on the used columns, 0 elsewhere.
        """
        scaler = self.pipeline_.named_steps["scale"]
        svm = self.pipeline_.named_steps["svm"]
        Z = (X[:, self.dims_] - scaler.mean_) / scaler.scale_
        V = svm.support_vectors_
        c = svm.dual_coef_[0]
        gamma = float(svm.gamma)  # always numeric: it comes from the grid
        sq = (Z * Z).sum(1)[:, None] - 2.0 * Z @ V.T + (V * V).sum(1)[None, :]
        Kc = np.exp(-gamma * np.maximum(sq, 0.0)) * c[None, :]
        f = Kc.sum(1) + svm.intercept_[0]
        if not gradient:
            return f, None
        dz = -2.0 * gamma * (Z * Kc.sum(1)[:, None] - Kc @ V)
        G = np.zeros_like(X)
        G[:, self.dims_] = dz / scaler.scale_[None, :]
        return f, G

    def predict(self, X) -> np.ndarray:
        """(n,) bool: predicted success."""
        X = self._check(X)
        if self.constant_ is not None:
            return np.full(len(X), self.constant_ >= 0.5)
        return self.decision_function(X) > 0

    def success_proba(self, X) -> np.ndarray:
        """(n,) calibrated P(success | x)."""
        X = self._check(X)
        if self.constant_ is not None:
            return np.full(len(X), self.constant_)
        a, b = self.platt_
        return expit(-(a * self.decision_function(X) + b))

    def predict_proba(self, X) -> np.ndarray:
        """(n, 2) probabilities of ``classes_`` = [failure, success]."""
        p = self.success_proba(X)
        return np.column_stack([1 - p, p])

    def decision_gradient(self, X) -> np.ndarray:
        """(n, d) gradient of :meth:`decision_function` with respect to the design vector
        (zeros outside ``dims_`` and in the one-class case)."""
        X = self._check(X)
        if self.constant_ is not None:
            return np.zeros_like(X)
        return self._decision(X, gradient=True)[1]

    def success_proba_gradient(self, X) -> np.ndarray:
        """(n, d) gradient of :meth:`success_proba`: ``-a p (1 - p) df/dx``."""
        return self.success_proba_and_gradient(X)[1]

    def success_proba_and_gradient(self, X) -> tuple[np.ndarray, np.ndarray]:
        """(n,) :meth:`success_proba` and (n, d) its gradient, in one pass."""
        X = self._check(X)
        if self.constant_ is not None:
            return np.full(len(X), self.constant_), np.zeros_like(X)
        a, b = self.platt_
        f, G = self._decision(X, gradient=True)
        p = expit(-(a * f + b))
        return p, (-a * p * (1 - p))[:, None] * G


# --- training helpers (module level so that they can be sent to worker processes) ---------


def _svm(params) -> SVC:
    return SVC(kernel="rbf", C=float(params["C"]), gamma=float(params["gamma"]),
               class_weight=params["class_weight"], cache_size=512)


def _fit_fold(Z, y, train, test, params):
    """Fit scaler and SVM on ``train``; the decision values on ``test``, or the fitted
    pipeline when ``test`` is None."""
    model = Pipeline([("scale", StandardScaler()), ("svm", _svm(params))]).fit(Z[train], y[train])
    return model if test is None else model.decision_function(Z[test])


# Largest training part whose RBF kernel the grid search computes in numpy (a float64
# matrix of 72 MB); larger folds let libsvm compute kernel values as it needs them.
_PRECOMPUTED_MAX_ROWS = 3000


def _score_settings(Z, y, train, test, settings):
    """Accuracy on ``test`` of an SVM fitted on ``train`` for each setting; the fold is
    standardised once.

    Settings that share a gamma share one kernel matrix, computed in numpy and given to
    libsvm as a precomputed kernel: on BALLRUN's recorded searches (967 to 1660 samples, 49
    settings, 3 folds) this took 8.5 s instead of 19.7 s, with the same 441 accuracies.
    (libsvm's own RBF kernel computes every value again for each C.)"""
    scaler = StandardScaler().fit(Z[train])
    A, B = scaler.transform(Z[train]), scaler.transform(Z[test])
    ytrain, ytest = y[train], y[test]
    if len(train) > _PRECOMPUTED_MAX_ROWS:
        return [float(np.mean((_svm(p).fit(A, ytrain).decision_function(B) > 0) == ytest))
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
        svm = SVC(kernel="precomputed", C=float(p["C"]), class_weight=p["class_weight"],
                  cache_size=512).fit(K_train, ytrain)
        f = K_test[:, svm.support_] @ svm.dual_coef_[0] + svm.intercept_[0]
        scores.append(float(np.mean((f > 0) == ytest)))
    return scores


def _grid_search(Z, y, C_grid, gamma_grid, class_weights, folds, n_jobs, halving=1,
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
    subsets = [_stratified_order(y, train, rs) for train, _ in splits]
    alive = np.arange(len(grid))
    for rung in range(rungs + 1):
        share = float(halving) ** (rung - rungs)
        scores = _score_grid(Z, y, splits, subsets, share, [grid[i] for i in alive], n_jobs)
        if rung < rungs:  # keep the best 1/eta, ties in grid order
            keep = max(2, int(np.ceil(len(alive) / halving)))
            alive = np.sort(alive[np.argsort(-scores, kind="stable")[:keep]])
    best = int(np.argmax(scores))
    return dict(grid[alive[best]]), float(scores[best])


def _stratified_order(y, train, rs):
    """The rows of ``train`` in an order whose every prefix keeps the class proportions
    (each class shuffled, then the two interleaved by rank)."""
    parts = [train[y[train] == c] for c in (False, True)]
    keys = [(np.arange(len(p)) + rs.random_sample(len(p))) / max(len(p), 1) for p in parts]
    rows = np.concatenate([rs.permutation(p) for p in parts])
    return rows[np.argsort(np.concatenate(keys), kind="stable")]


def _score_grid(Z, y, splits, subsets, share, settings, n_jobs):
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
    for (k, idx), acc in zip(where, parallel_map(_score_settings, jobs, n_jobs), strict=True):
        scores[k, idx] = acc
    return scores.mean(axis=0)


def _platt(f: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Platt's ``(a, b)``: maximum likelihood of ``P(y | f) = 1 / (1 + exp(a f + b))`` with
    his smoothed targets ``(n+ + 1) / (n+ + 2)`` and ``1 / (n- + 2)``."""
    n_pos = float(np.sum(y))
    n_neg = len(y) - n_pos
    t = np.where(y, (n_pos + 1.0) / (n_pos + 2.0), 1.0 / (n_neg + 2.0))
    scale = max(float(np.std(f)), 1e-12)  # fit on f / scale for conditioning
    g = f / scale

    def nll(ab):
        z = -(ab[0] * g + ab[1])  # log p = log_expit(z)
        loss = -np.sum(t * log_expit(z) + (1 - t) * log_expit(-z))
        r = t - expit(z)  # d loss / dz = -(t - p)
        return loss, np.array([np.sum(r * g), np.sum(r)])

    b0 = float(np.log((n_neg + 1.0) / (n_pos + 1.0)))
    res = minimize(nll, np.array([0.0, b0]), jac=True, method="L-BFGS-B")
    return float(res.x[0] / scale), float(res.x[1])
