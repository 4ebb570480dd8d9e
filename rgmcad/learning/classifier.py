"""The success classifier: a cross-validated RBF SVM with Platt-calibrated probabilities and
their analytic gradient (paper sections 5.2-5.3, authors' ``train_svc``).

Pipeline: optional column subset (the event's subspace) -> ``StandardScaler`` -> ``SVC(rbf)``,
with C, gamma and the class weighting chosen by a stratified-k-fold grid search (or given,
see ``params``). The probability is Platt's sigmoid ``p = 1 / (1 + exp(a f(x) + b))`` of the
decision function ``f``, fitted on out-of-fold decision values of ``calibration_folds``
folds; the same out-of-fold values give the model's accuracy. Then one SVM is fitted on all
the data.

Out-of-fold Platt scaling rather than ``SVC(probability=True)`` (libsvm's internal scaling,
which the authors used): at least as well calibrated, ``predict`` and ``predict_proba`` come
from one model, and the folds are seeded from ``random_state``. The grid search is
:mod:`.gridsearch`. Measurements: docs/decisions.md (2026-12-01, "The success classifier").
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize
from scipy.special import expit, log_expit
from sklearn.base import BaseEstimator, ClassifierMixin
from sklearn.model_selection import StratifiedKFold
from sklearn.utils import check_random_state
from sklearn.utils.validation import check_array, check_is_fitted

from .gridsearch import fit_fold, grid_search
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
            self.best_params_, self.search_accuracy_ = grid_search(
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
        *parts, self.pipeline_ = parallel_map(fit_fold, jobs, self.n_jobs)
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
        # not check_array: too slow over a run's thousands of small calls (docs/decisions.md)
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
