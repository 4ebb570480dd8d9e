"""Success-probability model of a whole causal graph, factorised per event (paper section 6,
authors' ``map_events_to_dimensions``).

``P(success | x) = prod_i P(E_i = success | parents succeeded, x)`` (Eq. 5), each factor a
conditional model (CSPD) over a low-dimensional subspace ``D_i``:

* the data of event ``E_i`` are the samples whose parents all succeeded and whose label for
  ``E_i`` is not None (the paper's rule plus the authors' "resolved" filter);
* quasi-deterministic events (success rate >= ``quasi_deterministic_rate``) get probability 1
  and no model;
* the others keep the dimensions that carry information about ``E_i``: by default a
  forward selection on the joint mutual information against a permutation null (see
  :func:`select_dimensions`; the authors' per-dimension rule is ``mi_selection =
  "marginal"``), and get a classifier trained by active learning on that subspace;
* an uncertain event with no informative dimension gets a constant probability, its
  smoothed success rate (the authors give it none, i.e. 1).

The "full" variant (``factorized=False``) is a single model of the global success over all
dimensions, stored under the name :data:`GLOBAL_EVENT`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Collection, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from .active import learn_active
from .classifier import SuccessClassifier
from .dimensions import EventAnalysis, analyse_event
from .graph import SuccessLogic, ancestors, topological_events
from .oracles import Label
from .settings import LearningSettings

__all__ = [
    "GLOBAL_EVENT",
    "ConstantModel",
    "SPDModel",
    "SPDFit",
    "event_dataset",
    "global_dataset",
    "smooth_min",
    "fit_spd",
]

logger = logging.getLogger(__name__)

GLOBAL_EVENT = "<global>"
"""Name of the single factor of the non-factorised ("full") model."""

SimulateFn = Callable[[np.ndarray, str], list[Label]]
ValidityFn = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class ConstantModel:
    """A factor with a constant probability (quasi-deterministic or uninformative event).

    Attributes
    ----------
    probability : float
    reason : str
        ``"quasi-deterministic"``, ``"no informative dimension"`` or ``"no data"``.
    """

    probability: float
    reason: str

    is_constant = True  # class attributes shared with SuccessClassifier's interface
    dims_ = ()

    def success_proba(self, X) -> np.ndarray:
        return np.full(len(np.atleast_2d(X)), self.probability)

    def success_proba_gradient(self, X) -> np.ndarray:
        return np.zeros_like(np.atleast_2d(np.asarray(X, dtype=float)))

    def success_proba_and_gradient(self, X) -> tuple[np.ndarray, np.ndarray]:
        return self.success_proba(X), self.success_proba_gradient(X)


EventModel = SuccessClassifier | ConstantModel


def event_dataset(
    X: np.ndarray,
    labels: Sequence[Label],
    event: str,
    parents: Sequence[str],
) -> tuple[np.ndarray, np.ndarray]:
    """Samples on which ``event`` is defined and its labels.

    A sample counts if it is valid, all ``parents`` succeeded and the event's label is not
    None.

    Returns
    -------
    X_event : (m, d) float
    y_event : (m,) bool
    """
    keep, y = [], []
    for i, lab in enumerate(labels):
        v = lab.events.get(event)
        if lab.valid and v is not None and all(lab.events.get(p) is True for p in parents):
            keep.append(i)
            y.append(bool(v))
    X = np.asarray(X, dtype=float)
    return X[keep].reshape(len(keep), X.shape[1]), np.array(y, dtype=bool)


def global_dataset(X: np.ndarray, labels: Sequence[Label]) -> tuple[np.ndarray, np.ndarray]:
    """Valid samples and their global success."""
    keep = [i for i, lab in enumerate(labels) if lab.valid]
    X = np.asarray(X, dtype=float)
    return X[keep].reshape(len(keep), X.shape[1]), np.array(
        [labels[i].success for i in keep], dtype=bool
    )


def smooth_min(r: np.ndarray, alpha: float) -> tuple[float, np.ndarray]:
    """Smooth minimum ``S = sum r_i e^{-alpha r_i} / sum e^{-alpha r_i}`` and dS/dr.

    ``dS/dr_i = w_i (1 - alpha (r_i - S))`` with ``w_i = e^{-alpha r_i} / sum_j e^{-alpha r_j}``.
    """
    r = np.asarray(r, dtype=float)
    e = np.exp(-alpha * (r - r.min()))  # shifted for stability; w is unchanged
    w = e / e.sum()
    s = float(w @ r)
    return s, w * (1.0 - alpha * (r - s))


@dataclass(frozen=True)
class SPDModel:
    """The learnt success-probability model.

    Attributes
    ----------
    events : tuple of str
        Factor names in topological order (``(GLOBAL_EVENT,)`` when not factorised).
    models : Mapping[str, SuccessClassifier | ConstantModel]
        One model per factor.
    factorized : bool
    alpha : float
        Smooth-minimum sharpness of :meth:`objective`.
    include_certain_events : bool
        Whether constant factors enter :meth:`objective`.
    dimension : int
        d (informative; 0 when unknown).
    logic : SuccessLogic or None
        How the factors combine into the graph's success (None: every factor must succeed,
        Eq. 6; otherwise any-joins make alternatives, see :mod:`.logic`).
    """

    events: tuple[str, ...]
    models: Mapping[str, EventModel]
    factorized: bool
    alpha: float = 1.0
    include_certain_events: bool = False
    dimension: int = 0
    logic: SuccessLogic | None = None

    @property
    def _alternatives(self) -> bool:
        return self.logic is not None and not self.logic.is_conjunction

    @property
    def learned_events(self) -> tuple[str, ...]:
        """Factors with a non-constant model."""
        return tuple(e for e in self.events if not self.models[e].is_constant)

    @property
    def objective_events(self) -> tuple[str, ...]:
        """Factors that enter the smooth minimum."""
        return self.events if self.include_certain_events else self.learned_events

    def event_probabilities(self, X) -> dict[str, np.ndarray]:
        """Per factor, (n,) P(factor succeeds | its parents succeeded, x)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return {e: self.models[e].success_proba(X) for e in self.events}

    def success_proba(self, X) -> np.ndarray:
        """(n,) predicted P(the whole graph succeeds | x): the product of the factors
        (Eq. 6), or with any-joins the probability that one alternative succeeds where the
        graph offers several."""
        probs = self.event_probabilities(X)
        if self._alternatives:
            return self.logic.probability(probs)
        return np.prod(np.stack(list(probs.values())), axis=0)

    def requirement_probabilities(self, X) -> dict[str, np.ndarray]:
        """Per requirement of the graph's success (an event, or a group of alternatives named
        ``any(...)``), its (n,) probability; with all-joins, the factors themselves."""
        probs = self.event_probabilities(X)
        if not self._alternatives:
            return probs
        return {r.name: self.logic.requirement_probability(r, probs)
                for r in self.logic.requirements}

    def weakest_link(self, x) -> tuple[str | None, float]:
        """The least probable requirement at ``x`` (d,) and its probability."""
        probs = {k: float(v[0]) for k, v in self.requirement_probabilities(
            np.asarray(x, dtype=float).reshape(1, -1)).items()}
        if not probs:
            return None, 1.0
        name = min(probs, key=probs.get)
        return name, probs[name]

    def objective(self, x, offsets: np.ndarray | None = None,
                  weights: np.ndarray | None = None) -> tuple[float, np.ndarray]:
        """Smooth minimum of the factors' probabilities at ``x`` (d,) and its gradient (d,).

        Factors are those of :attr:`objective_events`; with none, the objective is the
        (constant) product and the gradient is 0.

        Parameters
        ----------
        x : (d,) float
        offsets : (k, d) float, optional
            Placement errors: each factor's probability is then averaged over
            ``x + offsets`` (the expected success of the factor when the layout is built
            with those errors) before the smooth minimum.
        weights : (k,) float, optional
            Weights of that average (summing to 1; default: equal).
        """
        x = np.asarray(x, dtype=float).reshape(1, -1)
        if self._alternatives:
            return self._objective_with_alternatives(x, offsets, weights)
        names = self.objective_events
        if not names:
            return float(self.success_proba(x)[0]), np.zeros(x.shape[1])
        P = x if offsets is None else x + np.asarray(offsets, dtype=float)
        r = np.empty(len(names))
        G = np.empty((len(names), x.shape[1]))
        for i, e in enumerate(names):
            p, g = self.models[e].success_proba_and_gradient(P)
            r[i], G[i] = _average(p, weights), _average(g, weights)
        s, ds = smooth_min(r, self.alpha)
        return s, ds @ G

    def _objective_with_alternatives(self, x, offsets, weights) -> tuple[float, np.ndarray]:
        """:meth:`objective` over the requirements: a group of alternatives enters as the
        probability that one of them succeeds (its gradient by the chain rule through the
        multilinear group probability)."""
        learned = set(self.learned_events)
        terms = [r for r in self.logic.requirements
                 if self.include_certain_events or learned & set(r.events)]
        if not terms:
            return float(self.success_proba(x)[0]), np.zeros(x.shape[1])
        P = x if offsets is None else x + np.asarray(offsets, dtype=float)
        probs, grads = {}, {}
        for e in {e for r in terms for e in r.events}:
            probs[e], grads[e] = self.models[e].success_proba_and_gradient(P)
        r = np.empty(len(terms))
        G = np.empty((len(terms), x.shape[1]))
        for i, term in enumerate(terms):
            r[i] = _average(self.logic.requirement_probability(term, probs), weights)
            sens = self.logic.requirement_sensitivity(term, probs)
            G[i] = sum(_average(sens[e][:, None] * grads[e], weights) for e in term.events)
        s, ds = smooth_min(r, self.alpha)
        return s, ds @ G


def _average(a: np.ndarray, weights: np.ndarray | None) -> np.ndarray:
    """Mean of ``a`` over its first axis, weighted when ``weights`` is given."""
    return a.mean(axis=0) if weights is None else np.tensordot(weights, a, axes=(0, 0))


@dataclass(frozen=True)
class SPDFit:
    """Result of :func:`fit_spd`.

    Attributes
    ----------
    model : SPDModel
    analyses : Mapping[str, EventAnalysis]
        Per event (empty when not factorised).
    n_simulations : Mapping[str, int]
        Active-learning simulations per factor.
    n_labelled : Mapping[str, int]
        Of those, the ones that gave the factor a label.
    accuracy : Mapping[str, tuple[float, ...]]
        Cross-validated accuracy history per learnt factor.
    """

    model: SPDModel
    analyses: Mapping[str, EventAnalysis]
    n_simulations: Mapping[str, int]
    n_labelled: Mapping[str, int]
    accuracy: Mapping[str, tuple[float, ...]]


def fit_spd(
    X: np.ndarray,
    labels: Sequence[Label],
    event_parents: Mapping[str, Sequence[str]],
    validity: ValidityFn,
    simulate: SimulateFn,
    settings: LearningSettings,
    rng: np.random.Generator,
    any_joins: Collection[str] = frozenset(),
) -> SPDFit:
    """Learn the success-probability model from exploration data (paper sections 5.2-6).

    Parameters
    ----------
    X : (n, d) float
        Exploration samples.
    labels : sequence of Label
        Their labels.
    event_parents : Mapping[str, tuple[str, ...]]
        The causal graph.
    validity : callable
        ``validity(X) -> (k,) bool``.
    simulate : callable
        ``simulate(Q, stage) -> list[Label]``: simulates active-learning queries; ``stage``
        names the factor being learnt (``"active:<event>"`` or ``"active"``), for
        bookkeeping.
    settings : LearningSettings
    rng : numpy.random.Generator
    any_joins : collection of str
        Events that wake when any parent succeeded. Such an event's factor is learnt on the
        samples where it woke (its label is None otherwise), and the model combines the
        factors according to the graph (see :mod:`.logic`).

    Returns
    -------
    SPDFit
    """
    X = np.asarray(X, dtype=float)
    d = X.shape[1]
    s = settings
    if not s.factorized:
        Xg, yg = global_dataset(X, labels)

        def label_global(Q):
            return [lab.success if lab.valid else None for lab in simulate(Q, "active")]

        res = learn_active(Xg, yg, label_global, validity, s, rng)
        model = SPDModel(
            (GLOBAL_EVENT,), {GLOBAL_EVENT: res.classifier}, False, s.smooth_min_alpha,
            s.include_certain_events, d,
        )
        return SPDFit(
            model, {}, {GLOBAL_EVENT: res.n_queries}, {GLOBAL_EVENT: res.n_labelled},
            {GLOBAL_EVENT: res.accuracy_history},
        )

    order = topological_events(event_parents)
    logic = SuccessLogic(event_parents, frozenset(any_joins))
    # the parents a factor is conditioned on: an any-join's label already says it woke
    event_parents = {e: () if e in logic.any_joins else tuple(ps)
                     for e, ps in event_parents.items()}
    # Running record of every labelled sample (exploration first, then queries in order).
    all_X: list[np.ndarray] = [X]
    all_labels: list[Label] = list(labels)
    models: dict[str, EventModel] = {}
    analyses: dict[str, EventAnalysis] = {}
    n_sim: dict[str, int] = {}
    n_lab: dict[str, int] = {}
    acc: dict[str, tuple[float, ...]] = {}

    for event in order:
        parents = tuple(event_parents[event])
        Xe, ye = event_dataset(X, labels, event, parents)
        analysis = analyse_event(Xe, ye, event, s, int(rng.integers(2**31 - 1)))
        analyses[event] = analysis
        if analysis.n_samples == 0:
            logger.warning("event %r: no exploration sample where its parents succeeded", event)
            models[event] = ConstantModel(0.5, "no data")
            continue
        if analysis.quasi_deterministic:
            models[event] = ConstantModel(1.0, "quasi-deterministic")
            continue
        if not analysis.dims:
            p = (float(np.sum(ye)) + 1.0) / (len(ye) + 2.0)
            models[event] = ConstantModel(p, "no informative dimension")
            continue

        def label_event(Q, event=event, parents=parents):
            out = simulate(Q, f"active:{event}")
            all_X.append(Q)
            all_labels.extend(out)
            return [
                lab.events.get(event)
                if lab.valid and all(lab.events.get(p) is True for p in parents)
                else None
                for lab in out
            ]

        if s.share_samples:
            Xtrain, ytrain = event_dataset(np.vstack(all_X), all_labels, event, parents)
        else:
            Xtrain, ytrain = Xe, ye
        accept = _ancestor_filter(models, ancestors(event_parents, event), s)
        res = learn_active(
            Xtrain, ytrain, label_event, validity, s, rng, dims=analysis.dims, accept=accept
        )
        models[event] = res.classifier
        n_sim[event] = res.n_queries
        n_lab[event] = res.n_labelled
        acc[event] = res.accuracy_history
        logger.info(
            "event %r: dims %s, %d queries (%d labelled), accuracy %.3f",
            event, analysis.dims, res.n_queries, res.n_labelled, res.classifier.cv_accuracy_,
        )
    model = SPDModel(order, models, True, s.smooth_min_alpha, s.include_certain_events, d,
                     logic=None if logic.is_conjunction else logic)
    return SPDFit(model, analyses, n_sim, n_lab, acc)


def _ancestor_filter(
    models: Mapping[str, EventModel], names: Sequence[str], settings: LearningSettings
):
    """Candidate filter: predicted P(all ancestors succeed) >= parent_probability_min."""
    learned = [models[a] for a in names if not models[a].is_constant]
    if not learned or settings.parent_probability_min <= 0:
        return None

    def accept(C: np.ndarray) -> np.ndarray:
        p = np.ones(len(C))
        for m in learned:
            p *= m.success_proba(C)
        return p >= settings.parent_probability_min

    return accept
