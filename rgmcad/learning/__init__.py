"""Learning the success probability of a design space and optimising a robust layout.

Paper sections 5-7 ("Designing Chain Reaction Contraptions from Causal Graphs"): initial
exploration (:func:`explore`), SVM classifiers with Platt-calibrated probabilities
(:class:`SuccessClassifier`), active learning (:func:`learn_active`), factorisation of the
success probability over the causal graph (:func:`fit_spd`), constrained refinement
(:func:`maximize_robustness`) and placement tolerances (:func:`placement_tolerance`).
:func:`learn_and_optimize` runs them all on a :class:`Problem`; :func:`verify_layout` then
lets the simulator choose the layout to return among the optimum and the best-rated
simulated successes, and :func:`second_look` learns again from that choice's simulations and
keeps a refined layout only when it wins by simulation.

Modules, in pipeline order: ``settings``, ``graph`` (the causal graph's order and success
logic), ``oracles`` (the simulator protocol and synthetic problems), ``sampling``,
``gridsearch`` (the SVM's search and fits), ``classifier``, ``active``, ``dimensions`` (which
parameters each event depends on), ``factorize``, ``optimize``, ``pipeline``, ``verify``,
``second_look``.
"""

import logging

from .active import ActiveLearningResult, learn_active, query_distribution, synthesize_queries
from .baselines import (
    BASELINES,
    BaselineResult,
    cmaes_search,
    gp_search,
    local_estimate,
    random_search,
    uniform_search,
)
from .classifier import SuccessClassifier
from .dimensions import EventAnalysis, analyse_event, select_dimensions
from .factorize import (
    GLOBAL_EVENT,
    ConstantModel,
    SPDFit,
    SPDModel,
    event_dataset,
    fit_spd,
    global_dataset,
    smooth_min,
)
from .graph import Requirement, SuccessLogic, ancestors, topological_events
from .optimize import (
    OptimizationResult,
    maximize_robustness,
    overlap_ends,
    placement_tolerance,
    range_ends,
    start_point,
)
from .oracles import (
    BallRegion,
    BoxRegion,
    Label,
    OracleEvent,
    Problem,
    ProductOracle,
    SlabRegion,
)
from .pipeline import LearningResult, Progress, learn_and_optimize
from .sampling import (
    Exploration,
    NoValidLayoutError,
    SobolStream,
    explore,
    first_valid,
    sample_mixture,
)
from .second_look import SecondLook, second_look
from .settings import LearningSettings
from .verify import Candidate, Verification, verify_layout

logging.getLogger(__name__).addHandler(logging.NullHandler())

__all__ = [
    "BASELINES",
    "BaselineResult",
    "cmaes_search",
    "gp_search",
    "local_estimate",
    "random_search",
    "uniform_search",
    "ActiveLearningResult",
    "BallRegion",
    "Candidate",
    "BoxRegion",
    "SlabRegion",
    "ConstantModel",
    "EventAnalysis",
    "Exploration",
    "GLOBAL_EVENT",
    "Label",
    "LearningResult",
    "LearningSettings",
    "NoValidLayoutError",
    "OptimizationResult",
    "OracleEvent",
    "Problem",
    "ProductOracle",
    "Progress",
    "Requirement",
    "SPDFit",
    "SPDModel",
    "SobolStream",
    "SuccessClassifier",
    "SuccessLogic",
    "Verification",
    "analyse_event",
    "ancestors",
    "event_dataset",
    "explore",
    "first_valid",
    "fit_spd",
    "global_dataset",
    "learn_active",
    "learn_and_optimize",
    "maximize_robustness",
    "overlap_ends",
    "placement_tolerance",
    "range_ends",
    "query_distribution",
    "sample_mixture",
    "select_dimensions",
    "smooth_min",
    "start_point",
    "synthesize_queries",
    "topological_events",
    "verify_layout",
    "second_look",
    "SecondLook",
]
