"""Every tunable of the learning and optimisation pipeline, with its default and why.

The defaults reproduce the settings behind the paper's Table 1 (the authors'
``plot_local_robustness.py``, SPEC section 5.7) where the paper and that code disagree (they
made the published numbers); where rgmcad departs from both, the field's comment says why.
Lengths are in the design space's unit cube ``[0, 1]^d`` (SPEC section 3.2).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Literal

import numpy as np

__all__ = ["LearningSettings", "BUDGETS", "budget"]


def _log_grid() -> tuple[float, ...]:
    return tuple(float(v) for v in np.logspace(-3, 3, 7))


@dataclass(frozen=True)
class LearningSettings:
    """Settings of exploration, classifier training, active learning, factorisation and
    layout optimisation; frozen (a run stores them), varied by :meth:`replace`.

    Attributes
    ----------
    n_initial : int, default 500
        N0: number of *valid* Sobol points simulated first (paper Alg. 1 and Table 1; the
        authors' optimisation demo used 1000).
    n_successes : int, default 100
        N+: exploration stops at this many global successes (paper: 200; every run of the
        authors' code, Table 1 and the demo, used 100).
    exploration_batch, exploration_max_iter : int, default 10, 500
        N_k: valid mixture draws per exploration iteration; k_e: cap on the iterations
        (paper, code; "never reached" per the paper).
    exploration_lag : int, default 1
        Batches of exploration that simulate while the next one is drawn (batch k is drawn
        from the batches before k - lag; 0 = the paper's sequential loop): the pool never
        waits for a batch's last simulation, at no measurable cost in what is found; the
        result depends on the lag, never on timing or workers ("Exploration overlap").
    exploration_variance : float, default 0.01
        sigma of Eq. 1: each mixture component has covariance ``sigma * I``. It is a
        **variance** (standard deviation 0.1), as in the authors' code; the paper's notation
        reads like a scale (SPEC section 9, item 2).
    exploration_keep_rate : float, default 0.2
        Added by rgmcad: target fraction of an exploration batch's draws that keep their
        progress (succeed in at least as many events as the sample they were drawn around).
        Above 0, the mixtures' step shrinks while fewer draws keep it and grows back (never
        past ``exploration_variance``) while more do (:func:`~.sampling.explore`); 0 is the
        paper's fixed step. Why (in many dimensions the paper's step undoes events that
        already worked): docs/decisions.md, "Exploration step".
    exploration_stall_batches : int, default 5
        K > 0 (rgmcad's): after K mixture batches in a row that left the N+ parents unchanged,
        ties at their lowest count go to the newest; 0: never (the paper). "Exploration stalls".
    exploration_stall_spacing : float, default 0.0
        s > 0 (rgmcad's, off): once stalled, parents keep s step lengths (the standard
        deviation times sqrt(d)) apart where they can. "Parents spread apart after a stall".
    exploration_move_share : float, default 1.0
        p < 1 (rgmcad's, off): each coordinate of a mixture draw moves with probability p, one
        at least, the rest keep the parent's; 1: all move. "Draws that move a few coordinates".
    exploration_staged : float, default 0.0
        q > 0 (rgmcad's): a share q of the mixture draws keep their parent's values on the
        coordinates of the events it achieved (the causal graph's). "Exploration in stages".
    sobol_scramble : bool, default True
        Scramble the Sobol sequence with the run's rng (the authors' was not, so all their
        runs started from the same points); it keeps the low-discrepancy property, avoids
        the corner point 0 and makes runs independent. False: every run starts alike.
    max_draws_factor : int, default 100
        At most ``max_draws_factor * n`` candidates are drawn to find ``n`` valid ones (the
        authors' ``100 * N`` in exploration, ``1000 * N_k`` = 100 x ``10 * N_k`` in active
        learning).
    svm_C_grid, svm_gamma_grid : tuple of float, default 10^-3 ... 10^3 (7 values)
        Logarithmic grids of the SVM's C and gamma (gamma for standardised features),
        as in the authors' ``train_svc``.
    svm_class_weights : tuple, default (None,)
        Class weightings of the grid search. The authors also tried ``"balanced"``, which a
        search for accuracy almost never picks, at twice the time; add it to try it.
    cv_folds : int, default 3
        Stratified folds of the grid search; its best mean accuracy is the model's
        "accuracy" (paper section 5.2). Unlike the authors' code, the folds are shuffled
        (with a seed from the run's rng): their unshuffled folds split the data in sampling
        order, so one fold held mostly the late, adaptively sampled points.
    calibration_folds : int, default 5
        Folds of the out-of-fold decision values that Platt's sigmoid is fitted to
        (libsvm's internal Platt scaling, which the authors used, also uses 5).
    search_halving : int, default 1
        Added by rgmcad, off by default: with eta > 1 the grid search is a successive
        halving (Jamieson and Talwalkar 2016); 1 is the authors' exhaustive search. Every
        setting is first scored on the same folds with each training part cut to a
        stratified subset of ``eta**-R`` of its rows, the best ``1 / eta`` of them again on
        ``eta`` times more rows, up to the whole training parts, where the choice is made
        (test parts always whole). Off: three seeds cannot tell whether it costs robustness.
        See docs/decisions.md, "Grid search: halving kept off, searches only when data grew".
    search_min_train : int, default 100
        Fewest training rows per fold in the first rung; ``R`` is the largest number of
        rungs that keeps at least this many (so small data sets get the exhaustive search).
    search_growth : float, default 0.25
        Added by rgmcad: during active learning the grid search is run again only once the
        training data has grown by more than this fraction since the last search; other
        refits keep the chosen C, gamma and class weighting. The authors searched at every
        iteration. Why: the searches took nearly all the time outside simulation while an
        iteration's queries add little to the data; searching again once the data has grown
        keeps more of active learning's gain than never searching again. See
        docs/decisions.md, "Grid search: halving kept off, searches only when data grew".
    n_jobs : int or None, default None
        joblib processes for the grid searches, calibration folds and mutual information
        estimates, unless an executor is lent with :func:`rgmcad.learning.parallel.jobs_on`
        (``rgmcad optimize`` lends its simulation pool). Results do not depend on it.
    active_batch : int, default 10
        N_k of Alg. 2: simulations per active-learning iteration (paper, code). The
        candidate pool is ``10 * active_batch`` valid points (paper, code).
    active_max_iter : int, default 5
        k_l: cap on active-learning iterations (paper, Table 1).
    accuracy_target : float, default 0.99
        Active learning stops once the cross-validated accuracy reaches this. Table 1 used
        0.99 (so all ``active_max_iter`` iterations practically always ran); the paper says
        0.9 (SPEC section 9, item 4).
    query_variance_scale : float, default 0.01
        Factor on the query covariance ``|f(x_sv)| * diag(1 / s)`` (s = standard deviation
        of each feature in the training data), SPEC section 5.3; 1.0 is the authors'
        distribution. rgmcad departs from it: on [0, 1]^d, s is about 0.29, so the authors'
        covariance has a standard deviation near 1.9, most draws are clipped onto the faces
        of the cube, and the queries land *farther* from the boundary than uniform samples.
        With 0.01 (standard deviation about 0.19 sqrt|f|) they land close to it and the
        accuracy rises. See docs/decisions.md, "Active-learning queries near the boundary".
    factorized : bool, default True
        Learn one conditional model per uncertain event (paper section 6). False learns a
        single model of the global success (the "full" variant of Fig. 16).
    quasi_deterministic_rate : float, default 0.95
        An event whose success rate (given its parents succeeded) is at least this is
        quasi-deterministic: probability 1, no model (paper and code).
    mi_selection : {"forward", "marginal"}, default "forward"
        How an event's subspace is chosen. ``"forward"`` (rgmcad): greedy forward selection
        on the joint mutual information ``I(E; x_S)``, adding the dimension with the largest
        gain while the gain beats the permutation floor below (column permuted).
        ``"marginal"`` (paper and authors): each dimension's own MI against
        ``mi_relative_threshold``. Why: a parameter can matter only jointly with another
        (whether SIMPLE's ball hits the first domino depends on the track's x, height and
        roll together), which the per-dimension rule misses. See docs/decisions.md, "Event
        dimensions: joint selection against a permutation floor".
    mi_relative_threshold : float, default 0.2
        Only with ``mi_selection = "marginal"``. A dimension is kept for an event when its
        mutual information with the event is above ``mi_relative_threshold * max_j MI_j``:
        the rule of every authors' run. Not the paper's absolute 0.2 nats: a binary label's
        MI is at most its entropy (0.33 nats at a 90 % success rate).
    mi_null_permutations : int, default 5
        Added by rgmcad: a dimension must also beat chance. Each candidate dimension is
        permuted this many times and the largest gain any of them reaches is the floor (a
        family-wise null level that adapts to the sample size and class balance; 0
        disables it). For ``"marginal"`` the label is permuted instead (the same null for
        one dimension alone). Why: the k-NN estimator scores dimensions independent of the
        label above 0, more so on small samples, so the relative rule alone (or a fixed
        floor) can keep a spurious dimension. The floor also keeps an event that depends on
        no dimension from getting noise dimensions (it then gets a constant probability).
        See docs/decisions.md, "Event dimensions: joint selection against a permutation
        floor".
    mi_neighbors : int, default 3
        k of the k-NN mutual-information estimator (scikit-learn's and the authors' value).
    share_samples : bool, default True
        Added by rgmcad: an event's model also trains on the samples queried for earlier
        events (their simulations label every event). The authors kept them separate.
    parent_probability_min : float, default 0.5
        Added by rgmcad: active-learning candidates of an event must have a predicted
        probability of at least this that all its ancestors succeed (product of the
        ancestors' models, quasi-deterministic ones counting 1). Queries whose parents fail
        return no label for the event and are wasted simulations.
    smooth_min_alpha : float, default 1.0
        alpha of the smooth minimum ``S(r) = sum r_i e^{-alpha r_i} / sum e^{-alpha r_i}``
        (authors' value; the paper gives none). For probabilities in [0, 1], alpha <= 1 is
        exactly the range where S never decreases when one r_i increases
        (dS/dr_i = w_i (1 - alpha (r_i - S)) >= 0), so 1 is the sharpest monotone choice.
    include_certain_events : bool, default False
        Whether quasi-deterministic and constant events enter the smooth minimum as their
        (constant) probability. The authors leave them out (SPEC section 9, item 5): they
        carry no gradient and would only dilute the weights.
    placement_noise : float, default 0.05
        Added by rgmcad; used when ``error_radius`` is 0. Standard deviation (normalised
        units) of the placement errors the refinement should withstand: each factor's
        probability is averaged over ``x + e`` for ``placement_samples`` fixed Gaussian
        errors ``e`` before the smooth minimum. 0 (with ``error_radius`` 0) is the paper's
        objective. Why: the calibrated probabilities saturate near 1 a
        short way inside a success region, most steeply for sharp, deterministic
        outcomes, so the paper's objective has almost no gradient there and leaves the
        layout wherever it first became "certain"; averaged over errors, it rewards layouts
        that survive them. See docs/decisions.md, "Refinement with COBYLA, averaged over
        placement errors".
    error_radius : float, default 1.0
        Added by rgmcad. When positive, the errors the refinement, the ranking of
        candidates and the final choice by simulation average over are those of global
        robustness instead of Gaussian placement errors: a radius uniform in ``[0,
        error_radius]``, a point uniform in the ball of that radius intersected with the
        design space (normalised units). At 1 the expected success under them is ``rho_g``
        itself, the figure layouts are judged by. Why 1: on ballrun (3 seeds) and
        causality_switch the returned layouts' rho_g rose from 0.52 to 0.60; see
        docs/decisions.md, "Optimising for global robustness" and
        :mod:`rgmcad.learning.errors`.
    placement_samples : int, default 128
        Number of errors the refinement averages over (a quasi-random design, rounded up
        to a power of two; for ball errors, in 8 radii).
    optimizer : {"cobyla", "auglag", "slsqp"}, default "cobyla"
        nlopt method for the constrained refinement. ``"cobyla"`` (LN_COBYLA) handles the
        non-differentiable penetration constraint directly; ``"auglag"`` (LD_AUGLAG around
        LD_LBFGS) uses the analytic objective gradient and finite differences for the
        penetration. Why COBYLA: see :mod:`rgmcad.learning.optimize`; the measurements are in
        docs/decisions.md, "Refinement with COBYLA, averaged over placement errors". The
        authors used SciPy's SLSQP with finite differences.
    refine_starts : int, default 1
        Added by rgmcad. Refinements run, each from an explored valid sample: the one with
        the highest predicted success (the paper's single start), then those with the
        highest expected success under the refinement's errors; the best optimum is kept.
        They cost penetration tests, no simulation.
    optimizer_max_eval : int, default 400
        Cap on objective evaluations of the refinement.
    optimizer_xtol : float, default 1e-4
        Absolute tolerance on x (normalised units) that ends the refinement.
    optimizer_initial_step : float, default 0.05
        Initial step of the derivative-free method (normalised units).
    constraint_tolerance : float, default 1e-6
        Penetration accepted by the optimiser while it searches; the returned point is
        always one whose penetration was exactly 0.
    fd_step : float, default 1e-4
        Forward finite-difference step for the penetration's gradient ("auglag" only).
    unmodelled_at : {"start", "median"}, default "median"
        Added by rgmcad: where the refined layout puts a parameter no event's model depends
        on (the refinement cannot move it): "median", at the median of the run's simulated
        successes along it, each kept only if the layout stays valid; "start", where its
        start sample had it (the paper: a parameter can then stay at a bad end of its range
        by chance). See docs/decisions.md, "The pair by default".
    verify_candidates : int, default 4
        Added by rgmcad: layouts compared by simulation at the end (the optimum if it
        succeeds, then the simulated global successes the model rates highest); see
        :mod:`rgmcad.learning.verify`.
    verify_samples : int, default 256
        Errors per candidate (a power of two; of ``error_radius``, else Gaussian of
        ``verify_noise``; up to 4x while one has under half as many valid copies): they race
        from 32, doubling, one significantly below the leader dropped after each stage;
        0 keeps the paper's choice (the optimum if its one simulation succeeds, else
        the best rated simulated success). Why: the refinement maximises the model's
        prediction, which can be confidently wrong; choosing by simulation returns more
        robust layouts, and telling candidates 0.1 apart in rho_g takes a few hundred
        errors. See docs/decisions.md, "Final choice by simulation" and "The pair by
        default".
    verify_noise : float, default 0.05
        With ``error_radius`` 0: standard deviation (normalised units) of those placement
        errors, the same as ``placement_noise`` by default.
    centering : {"auto", "always", "off"}, default "auto"
        Added by rgmcad: when to centre the chosen layout in its success region by
        simulation (Gaussian adaptation, :mod:`rgmcad.learning.centering`); the centre
        replaces it only if it does better at ``centering_check_samples`` errors. "auto":
        when the exploration ended with fewer than ``n_successes`` global successes (the
        success model then rests on few, and the chosen layout tends to sit in a pocket near
        the edge of its region); "off": the paper's method. Why "auto" and not "always":
        where the exploration found its successes, the centre did worse than the chosen
        layout in 5 of the 6 shipped scenarios (docs/decisions.md, "Design centring").
    centering_simulations : int, default 320
        At most this many simulations for the centring (0: none). Needs ``verify_samples``
        > 0.
    centering_batch : int, default 16
        Valid layouts simulated per centring step.
    centering_hit_rate : float, default 0.3
        The fraction of successes the centring's radius is adapted to, in (0, 1).
    centering_check_samples : int, default 128
        Errors (the final choice's kind) at which the centre and the layout it came from
        are both simulated; the centre replaces that layout only if it succeeds more often.
    second_look : bool, default True
        Added by rgmcad: after the final choice, fit the model again on every simulation of
        the run (the choice's own included), refine again, and keep the refined layout only
        if it succeeds more often than the chosen one at ``verify_samples`` errors new to
        both (:mod:`rgmcad.learning.second_look`). Needs ``verify_samples`` > 0.
    second_look_rounds : int, default 1
        Looks at most: another runs, on every simulation so far, only after a look whose
        refined layout was kept. Added by rgmcad (docs/decisions.md, "Looking again").
    close_in_copies : int, default 0
        K > 0: the layout handed out must succeed at K valid layouts within 1/300 of it, else
        the one before it that does (:mod:`~.close_in`). Off: "Knife edges" in decisions.
    tolerance_ratio : float, default 0.9
        Placement tolerance: how far each coordinate may move before the predicted success
        probability drops below ``tolerance_ratio`` times its value at the optimum.
    tolerance_step : float, default 0.005
        Scan step of the tolerance search before bisection (normalised units).
    tolerance_bisections : int, default 12
        Bisection steps after the scan (resolution ``tolerance_step / 2**12``).
    """

    # Exploration (paper Alg. 1)
    n_initial: int = 500
    n_successes: int = 100
    exploration_batch: int = 10
    exploration_max_iter: int = 500
    exploration_lag: int = 1
    exploration_variance: float = 0.01
    exploration_keep_rate: float = 0.2
    exploration_stall_batches: int = 5
    exploration_stall_spacing: float = 0.0
    exploration_move_share: float = 1.0
    exploration_staged: float = 0.0
    sobol_scramble: bool = True
    max_draws_factor: int = 100
    # Classifier
    svm_C_grid: tuple[float, ...] = field(default_factory=_log_grid)
    svm_gamma_grid: tuple[float, ...] = field(default_factory=_log_grid)
    svm_class_weights: tuple[str | None, ...] = (None,)
    cv_folds: int = 3
    calibration_folds: int = 5
    search_halving: int = 1
    search_min_train: int = 100
    search_growth: float = 0.25
    n_jobs: int | None = None
    # Active learning (paper Alg. 2)
    active_batch: int = 10
    active_max_iter: int = 5
    accuracy_target: float = 0.99
    query_variance_scale: float = 0.01
    # Factorisation (paper section 6)
    factorized: bool = True
    quasi_deterministic_rate: float = 0.95
    mi_selection: Literal["forward", "marginal"] = "forward"
    mi_relative_threshold: float = 0.2
    mi_null_permutations: int = 5
    mi_neighbors: int = 3
    share_samples: bool = True
    parent_probability_min: float = 0.5
    # Optimisation (paper section 7)
    smooth_min_alpha: float = 1.0
    include_certain_events: bool = False
    placement_noise: float = 0.05
    error_radius: float = 1.0
    placement_samples: int = 128
    optimizer: Literal["cobyla", "auglag", "slsqp"] = "cobyla"
    refine_starts: int = 1
    optimizer_max_eval: int = 400
    optimizer_xtol: float = 1e-4
    optimizer_initial_step: float = 0.05
    constraint_tolerance: float = 1e-6
    fd_step: float = 1e-4
    unmodelled_at: Literal["start", "median"] = "median"
    # Choice of the final layout
    verify_candidates: int = 4
    verify_samples: int = 256
    verify_noise: float = 0.05
    centering: Literal["auto", "always", "off"] = "auto"
    centering_simulations: int = 320
    centering_batch: int = 16
    centering_hit_rate: float = 0.3
    centering_check_samples: int = 128
    second_look: bool = True
    second_look_rounds: int = 1
    close_in_copies: int = 0
    # Placement tolerance
    tolerance_ratio: float = 0.9
    tolerance_step: float = 0.005
    tolerance_bisections: int = 12

    def __post_init__(self):
        for name in ("n_initial", "n_successes", "exploration_batch", "max_draws_factor",
                     "cv_folds", "search_halving", "search_min_train", "calibration_folds",
                     "active_batch", "mi_neighbors", "optimizer_max_eval", "placement_samples",
                     "verify_candidates", "refine_starts", "centering_batch",
                     "centering_check_samples", "second_look_rounds"):
            value = getattr(self, name)
            if int(value) != value or value < 1:
                raise ValueError(f"LearningSettings.{name} must be a positive integer, got "
                                 f"{value!r}")
        for name in ("exploration_max_iter", "exploration_lag", "exploration_stall_batches",
                     "active_max_iter", "tolerance_bisections", "mi_null_permutations",
                     "verify_samples", "centering_simulations", "close_in_copies"):
            value = getattr(self, name)
            if int(value) != value or value < 0:
                raise ValueError(f"LearningSettings.{name} must be a non-negative integer, "
                                 f"got {value!r}")
        if not 0.0 < self.exploration_move_share <= 1.0:
            raise ValueError("LearningSettings.exploration_move_share must lie in (0, 1], got "
                             f"{self.exploration_move_share!r}")
        for name in ("accuracy_target", "quasi_deterministic_rate", "exploration_keep_rate",
                     "exploration_staged", "mi_relative_threshold", "parent_probability_min",
                     "tolerance_ratio"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"LearningSettings.{name} must lie in [0, 1], got {value!r}")
        for name in ("exploration_variance", "query_variance_scale", "optimizer_xtol", "verify_noise",
                     "optimizer_initial_step", "fd_step", "tolerance_step"):
            value = getattr(self, name)
            if not value > 0:
                raise ValueError(f"LearningSettings.{name} must be > 0, got {value!r}")
        for name in ("search_growth", "smooth_min_alpha", "constraint_tolerance",
                     "placement_noise", "exploration_stall_spacing"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"LearningSettings.{name} must be >= 0, got "
                                 f"{getattr(self, name)!r}")
        if not 0.0 < self.centering_hit_rate < 1.0:
            raise ValueError("LearningSettings.centering_hit_rate must lie in (0, 1), got "
                             f"{self.centering_hit_rate!r}")
        for name, allowed in (("centering", ("auto", "always", "off")),
                              ("unmodelled_at", ("start", "median")),
                              ("mi_selection", ("forward", "marginal")),
                              ("optimizer", ("cobyla", "auglag", "slsqp"))):
            if getattr(self, name) not in allowed:
                raise ValueError(f"LearningSettings.{name} must be one of {allowed}, got "
                                 f"{getattr(self, name)!r}")
        if self.centering != "off" and self.centering_simulations and not self.verify_samples:
            raise ValueError("LearningSettings.centering_simulations needs verify_samples > 0 "
                             "(the centre is judged by the final choice's errors)")
        if not 0.0 <= self.error_radius <= 2.0:
            raise ValueError(f"LearningSettings.error_radius must lie in [0, 2], got "
                             f"{self.error_radius!r}")
        if not self.svm_C_grid or not self.svm_gamma_grid or not self.svm_class_weights:
            raise ValueError("LearningSettings: the SVM grids must not be empty")
        if bad := [w for w in self.svm_class_weights if w not in (None, "balanced")]:
            raise ValueError(f"LearningSettings.svm_class_weights: {bad!r} not allowed; use "
                             "None or 'balanced'")

    def replace(self, **changes) -> LearningSettings:
        """A copy with some fields changed (unknown names raise ``TypeError``)."""
        names = {f.name for f in fields(self)}
        unknown = sorted(set(changes) - names)
        if unknown:
            raise TypeError(
                f"unknown LearningSettings field(s) {unknown}; valid: {sorted(names)}"
            )
        return replace(self, **changes)


BUDGETS = ("default", "small")
"""Names of the settings presets of :func:`budget` (``rgmcad optimize --budget``)."""


def budget(name: str) -> LearningSettings:
    """The :class:`LearningSettings` of a budget name.

    ``default`` is the settings behind the paper's Table 1 (SPEC 5.7; every default of
    ``LearningSettings`` is documented there). ``small`` is a quick look for trying a scenario
    out and for tests, not for results: N0 = 100 Sobol points, N+ = 20, at most 50
    exploration and 2 active-learning iterations, a 4 x 4 SVM grid, 16 placement errors,
    8 errors per candidate in the final choice, a centring of 64 simulations judged at 32
    errors.
    """
    if name == "default":
        return LearningSettings()
    if name == "small":
        return LearningSettings(
            n_initial=100, n_successes=20, exploration_max_iter=50, active_batch=10,
            active_max_iter=2, svm_C_grid=(0.1, 1.0, 10.0, 100.0),
            svm_gamma_grid=(0.1, 1.0, 10.0, 100.0), placement_samples=32,
            optimizer_max_eval=200, verify_samples=8, centering_simulations=64,
            centering_check_samples=32,
        )
    raise ValueError(f"unknown budget {name!r}; valid: {', '.join(BUDGETS)}")
