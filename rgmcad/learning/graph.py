"""The causal graph as the learner reads it: event order, ancestors, and whether the graph
succeeds as a function of its events' conditional probabilities.

Each event ``e`` has a factor ``p_e(x) = P(e succeeds | e woke, x)``. An event wakes when all
its parents succeeded (``join = "all"``) or when any of them did (``join = "any"``), and the
graph succeeds when every leaf succeeds. Treating the factors as independent given ``x`` (the
assumption of the paper's Eq. 5), success is a monotone Boolean formula over independent
events, and its probability is computed exactly here:

* with all-joins only, the formula is the conjunction of every event and its probability the
  product of the factors (Eq. 6);
* with an any-join, the alternatives form a disjunction ``P(a or b) = 1 - (1 - P(a))(1 - P(b))``
  when they share no event; an event shared by several branches of a conjunction or a
  disjunction (a common ancestor) is conditioned on (Shannon expansion), so it is counted once.

The formula is also split into its *requirements*, the terms of its top-level conjunction:
single events that must succeed, and groups of alternatives (an any-join's parent paths, with
the events every path needs moved out). The refinement maximises the smooth minimum of the
requirements' probabilities and the weakest link is the least probable requirement; with
all-joins the requirements are exactly the events, as in the paper.

Formulas are hashable tuples: ``("v", name)``, ``("and", frozenset)``, ``("or", frozenset)``,
:data:`TRUE` and :data:`FALSE`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import lru_cache
from graphlib import CycleError, TopologicalSorter

import numpy as np

__all__ = ["SuccessLogic", "Requirement", "topological_events", "ancestors"]


def topological_events(event_parents: Mapping[str, Sequence[str]]) -> tuple[str, ...]:
    """Events ordered so that every event comes after its parents.

    Ties keep the mapping's order, so the result is deterministic.

    Raises
    ------
    ValueError
        If a parent is not an event or the graph has a cycle.
    """
    names = list(event_parents)
    for e, parents in event_parents.items():
        missing = [p for p in parents if p not in event_parents]
        if missing:
            raise ValueError(
                f"event {e!r} waits for unknown event(s) {missing}; events are {names}"
            )
    sorter = TopologicalSorter({e: tuple(event_parents[e]) for e in names})
    try:
        sorter.prepare()
    except CycleError as err:
        raise ValueError(f"the causal graph has a cycle: {err.args[1]}") from None
    rank = {e: i for i, e in enumerate(names)}
    order: list[str] = []
    while sorter.is_active():
        ready = sorted(sorter.get_ready(), key=rank.__getitem__)
        order.extend(ready)
        sorter.done(*ready)
    return tuple(order)


def ancestors(event_parents: Mapping[str, Sequence[str]], event: str) -> tuple[str, ...]:
    """All ancestors of ``event`` (parents, their parents, ...), in topological order."""
    seen: set[str] = set()
    stack = list(event_parents[event])
    while stack:
        e = stack.pop()
        if e not in seen:
            seen.add(e)
            stack.extend(event_parents[e])
    return tuple(e for e in topological_events(event_parents) if e in seen)

TRUE = ("true",)
FALSE = ("false",)


def _var(name: str) -> tuple:
    return ("v", name)


def _and(children) -> tuple:
    flat: set[tuple] = set()
    for c in children:
        if c == FALSE:
            return FALSE
        if c == TRUE:
            continue
        flat.update(c[1] if c[0] == "and" else (c,))
    if not flat:
        return TRUE
    return next(iter(flat)) if len(flat) == 1 else ("and", frozenset(flat))


def _required(node: tuple) -> frozenset[tuple]:
    """The conjuncts of ``node`` (itself when it is not a conjunction)."""
    return node[1] if node[0] == "and" else frozenset((node,))


def _or(children) -> tuple:
    flat: set[tuple] = set()
    for c in children:
        if c == TRUE:
            return TRUE
        if c == FALSE:
            continue
        flat.update(c[1] if c[0] == "or" else (c,))
    if not flat:
        return FALSE
    if len(flat) == 1:
        return next(iter(flat))
    # a conjunct every alternative needs comes out: (a and r) or (b and r) = r and (a or b)
    common = frozenset.intersection(*(_required(c) for c in flat))
    if common:
        rest = _or(_and(_required(c) - common) for c in flat)
        return _and([*common, rest])
    return ("or", frozenset(flat))


def _variables(node: tuple) -> frozenset[str]:
    if node[0] == "v":
        return frozenset((node[1],))
    if node[0] in ("and", "or"):
        return frozenset().union(*(_variables(c) for c in node[1]))
    return frozenset()


@lru_cache(maxsize=4096)
def _substitute(node: tuple, name: str, value: bool) -> tuple:
    """``node`` with event ``name`` set to ``value``, simplified."""
    kind = node[0]
    if kind == "v":
        return (TRUE if value else FALSE) if node[1] == name else node
    if kind in ("and", "or"):
        children = [_substitute(c, name, value) for c in node[1]]
        return _and(children) if kind == "and" else _or(children)
    return node


@lru_cache(maxsize=4096)
def _shared(node: tuple) -> str | None:
    """An event that occurs in two or more children of ``node`` (None if none does); the
    smallest name, so that the expansion order is deterministic."""
    if node[0] not in ("and", "or"):
        return None
    seen: set[str] = set()
    shared: set[str] = set()
    for c in node[1]:
        names = _variables(c)
        shared |= seen & names
        seen |= names
    return min(shared) if shared else None


def _children(node: tuple) -> list[tuple]:
    return sorted(node[1])  # a fixed order: products are then bit-reproducible


def _probability(node: tuple, p: Mapping[str, np.ndarray], n: int) -> np.ndarray:
    kind = node[0]
    if kind == "v":
        return p[node[1]]
    if kind == "true":
        return np.ones(n)
    if kind == "false":
        return np.zeros(n)
    pivot = _shared(node)
    if pivot is not None:
        high = _probability(_substitute(node, pivot, True), p, n)
        low = _probability(_substitute(node, pivot, False), p, n)
        return p[pivot] * high + (1.0 - p[pivot]) * low
    if kind == "and":
        out = np.ones(n)
        for c in _children(node):
            out = out * _probability(c, p, n)
        return out
    miss = np.ones(n)
    for c in _children(node):
        miss = miss * (1.0 - _probability(c, p, n))
    return 1.0 - miss


@dataclass(frozen=True)
class Requirement:
    """One term of the success formula's top-level conjunction: an event that must succeed,
    or a group of alternatives (its formula then given that the required events succeed).

    Attributes
    ----------
    name : str
        The event's name, or ``any(a, b)`` for a group of alternatives (named by the parents
        of the any-join it stands for).
    formula : tuple
        The term (see the module docstring).
    events : tuple of str
        The events it depends on, sorted.
    """

    name: str
    formula: tuple
    events: tuple[str, ...]

    @property
    def is_event(self) -> bool:
        return self.formula[0] == "v"


@dataclass(frozen=True)
class SuccessLogic:
    """The success formula of a causal graph.

    Parameters
    ----------
    event_parents : Mapping[str, Sequence[str]]
        The causal graph: each event and the events it waits for.
    any_joins : collection of str
        Events that wake when any parent succeeded (the others wait for all).
    """

    event_parents: Mapping[str, Sequence[str]]
    any_joins: frozenset[str] = frozenset()
    formula: tuple = field(init=False, repr=False)
    requirements: tuple[Requirement, ...] = field(init=False, repr=False)

    def __post_init__(self):
        parents = {e: tuple(ps) for e, ps in self.event_parents.items()}
        joins = frozenset(self.any_joins)
        unknown = sorted(joins - set(parents))
        if unknown:
            raise ValueError(f"any_joins names unknown event(s) {unknown}")
        object.__setattr__(self, "event_parents", parents)
        object.__setattr__(self, "any_joins", joins)
        succeeds: dict[str, tuple] = {}
        labels: dict[tuple, str] = {}
        for e in topological_events(parents):
            above = [succeeds[q] for q in parents[e]]
            if e in joins and above:
                woke = _or(above)
                if woke[0] == "and":  # the group is what is left after the common events
                    groups = [c for c in woke[1] if c[0] == "or"]
                    if groups:
                        labels.setdefault(groups[0], f"any({', '.join(parents[e])})")
                elif woke[0] == "or":
                    labels.setdefault(woke, f"any({', '.join(parents[e])})")
            else:
                woke = _and(above)
            succeeds[e] = _and([_var(e), woke])
        has_child = {q for ps in parents.values() for q in ps}
        formula = _and(succeeds[e] for e in parents if e not in has_child)
        object.__setattr__(self, "formula", formula)
        rank = {e: i for i, e in enumerate(topological_events(parents))}
        conjuncts = _required(formula) if formula[0] != "true" else frozenset()
        required = sorted(c[1] for c in conjuncts if c[0] == "v")
        terms = []
        for term in conjuncts:
            name = term[1] if term[0] == "v" else labels.get(term)
            if term[0] != "v":  # a group counts given the events that must succeed anyway
                for e in required:
                    term = _substitute(term, e, True)
            events = tuple(sorted(_variables(term), key=rank.__getitem__))
            terms.append(Requirement(name or f"any of ({', '.join(events)})", term, events))
        terms.sort(key=lambda r: (min(rank[e] for e in r.events), r.name))
        object.__setattr__(self, "requirements", tuple(terms))

    @property
    def is_conjunction(self) -> bool:
        """True when success means every event succeeds (no any-join changes anything)."""
        return all(r.is_event for r in self.requirements) and len(self.requirements) == len(
            self.event_parents)

    def probability(self, p: Mapping[str, np.ndarray]) -> np.ndarray:
        """(n,) P(the graph succeeds) from each event's (n,) factor ``p[e]``."""
        n = len(next(iter(p.values())))
        return _probability(self.formula, p, n)

    def requirement_probability(self, term: Requirement, p: Mapping[str, np.ndarray]
                                ) -> np.ndarray:
        """(n,) probability of one requirement."""
        n = len(next(iter(p.values())))
        return _probability(term.formula, p, n)

    def requirement_sensitivity(self, term: Requirement, p: Mapping[str, np.ndarray]
                                ) -> dict[str, np.ndarray]:
        """Per event of ``term``, (n,) d P(term) / d p_e. The probability is multilinear in
        the factors, so the derivative is P(term | e succeeds) - P(term | e fails)."""
        n = len(next(iter(p.values())))
        return {e: _probability(_substitute(term.formula, e, True), p, n)
                - _probability(_substitute(term.formula, e, False), p, n)
                for e in term.events}
