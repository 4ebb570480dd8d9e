"""What the learner needs from a simulator, and synthetic simulators with known answers.

:class:`Problem` is the protocol the real simulator satisfies; :class:`Label` is the outcome of
one simulation. :class:`ProductOracle` is a stand-in with analytic answers: each event of a
causal graph succeeds (given that its parents did) iff the design vector lies in a region
defined over a known subset of the dimensions, and a few balls of the design space are
physically invalid, with penetration = depth inside the ball. Tests and examples use it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np

from .graph import SuccessLogic, topological_events

__all__ = [
    "Label",
    "Problem",
    "BoxRegion",
    "BallRegion",
    "OracleEvent",
    "ProductOracle",
    "chain_oracle",
]


@dataclass(frozen=True)
class Label:
    """The outcome of simulating one design vector.

    Attributes
    ----------
    valid : bool
        False when bodies intersect in the initial layout; such a layout is never simulated
        (``success`` is False and every event is None).
    success : bool
        True iff the whole causal graph succeeded.
    events : Mapping[str, bool | None]
        Per event: True success, False failure, None never woke up or unresolved when the
        run ended.
    """

    valid: bool
    success: bool
    events: Mapping[str, bool | None]

    @property
    def n_success(self) -> int:
        """Number of events that succeeded."""
        return sum(1 for v in self.events.values() if v is True)


@runtime_checkable
class Problem(Protocol):
    """A design problem: a design space ``[0, 1]^dimension`` and an expensive simulator.

    Attributes
    ----------
    dimension : int
        d, the length of a design vector.
    event_parents : Mapping[str, tuple[str, ...]]
        The causal graph, a DAG: each event and the events it waits for.
    any_joins : frozenset of str
        Events that wake when any of their parents succeeded; the others wait for all.
    """

    dimension: int
    event_parents: Mapping[str, tuple[str, ...]]
    any_joins: frozenset[str]

    def validity(self, X: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each row of ``X`` (n, d) in [0, 1]^d is physically valid."""
        ...

    def penetration(self, x: np.ndarray) -> float:
        """Penetration of the layout ``x`` (d,): >= 0, 0 iff valid, continuous."""
        ...

    def simulate(self, X: np.ndarray) -> list[Label]:
        """Simulate each row of ``X`` (n, d); one :class:`Label` per row, in order."""
        ...

    # Optional: ``event_dimensions``, a mapping of each event to the coordinates it depends
    # on (the parts it involves), which a staged exploration keeps fixed once the event
    # happened (:mod:`.moves`).
    # Optional: ``submit(X) -> wait``, which starts simulating ``X`` elsewhere (a process
    # pool) and returns ``wait() -> list[Label]``. The exploration then draws its next batch
    # while the last one simulates (``LearningSettings.exploration_lag``); without it, a
    # batch simply runs when waited for. Same labels either way.


# --- analytic regions -------------------------------------------------------------------------


class _Region:
    """What the regions share: membership from the signed distance."""

    def contains(self, Z: np.ndarray) -> np.ndarray:
        """(n,) bool: inside or on the boundary."""
        return self.signed_distance(Z) >= 0


@dataclass(frozen=True)
class BoxRegion(_Region):
    """Axis-aligned box ``lo <= z <= hi`` over a subset of the dimensions.

    Attributes
    ----------
    lo, hi : tuple of float
        Corners, one value per dimension of the subspace.
    """

    lo: tuple[float, ...]
    hi: tuple[float, ...]

    @property
    def dimension(self) -> int:
        return len(self.lo)

    def signed_distance(self, Z: np.ndarray) -> np.ndarray:
        """(n,) Euclidean distance to the box boundary, positive inside, negative outside."""
        Z = np.atleast_2d(Z)
        lo, hi = np.asarray(self.lo), np.asarray(self.hi)
        inside_margin = np.minimum(Z - lo, hi - Z)  # > 0 per axis when inside the slab
        outside = np.maximum(0.0, np.maximum(lo - Z, Z - hi))
        d_out = np.linalg.norm(outside, axis=1)
        d_in = inside_margin.min(axis=1)
        return np.where(d_out > 0, -d_out, d_in)

@dataclass(frozen=True)
class BallRegion(_Region):
    """Ball ``|z - centre| <= radius`` over a subset of the dimensions."""

    centre: tuple[float, ...]
    radius: float

    @property
    def dimension(self) -> int:
        return len(self.centre)

    def signed_distance(self, Z: np.ndarray) -> np.ndarray:
        """(n,) distance to the sphere, positive inside, negative outside."""
        Z = np.atleast_2d(Z)
        return self.radius - np.linalg.norm(Z - np.asarray(self.centre), axis=1)

@dataclass(frozen=True)
class SlabRegion(_Region):
    """Slab ``|n . z - offset| <= half_width`` over a subset of the dimensions, ``n`` the
    unit vector along ``normal``. Tilted slabs make dimensions that matter only jointly:
    with ``normal = (1, -0.3)``, ``P(success | z_1)`` is the same for every ``z_1`` away from
    the faces of the cube, yet ``z_1`` moves the region."""

    normal: tuple[float, ...]
    offset: float
    half_width: float

    @property
    def dimension(self) -> int:
        return len(self.normal)

    def signed_distance(self, Z: np.ndarray) -> np.ndarray:
        """(n,) distance to the nearer face, positive inside."""
        Z = np.atleast_2d(Z)
        n = np.asarray(self.normal, dtype=float)
        n = n / np.linalg.norm(n)
        return self.half_width - np.abs(Z @ n - self.offset)

@dataclass(frozen=True)
class OracleEvent:
    """One event of a :class:`ProductOracle`.

    Attributes
    ----------
    parents : tuple of str
        Events that must succeed before this one can happen.
    dims : tuple of int
        Dimensions the event depends on (its true subspace); empty = always succeeds.
    region : BoxRegion, BallRegion, SlabRegion or None
        Success region over ``dims``; None = always succeeds once the parents did.
    join : str
        ``"all"``: the event wakes when all its parents succeeded; ``"any"``: when one did.
    """

    parents: tuple[str, ...] = ()
    dims: tuple[int, ...] = ()
    region: BoxRegion | BallRegion | SlabRegion | None = None
    join: str = "all"


@dataclass(frozen=True)
class ProductOracle:
    """A synthetic :class:`Problem` with analytic success regions and invalid balls.

    Event ``e`` succeeds iff it woke (all its parents succeeded, or one of them for
    ``join="any"``) and ``x[dims_e]`` lies in its region; an event that never woke gets None.
    The whole graph succeeds when every leaf event does. Labels are a
    deterministic function of ``x`` and ``seed``, like a deterministic physics engine: the
    same point always gets the same label, whatever the order of the calls.

    Attributes
    ----------
    dimension : int
        d.
    events : Mapping[str, OracleEvent]
        The causal graph with each event's region.
    invalid_balls : tuple of (centre, radius)
        Full-dimensional balls of invalid layouts; penetration = depth inside the deepest.
    flip_probability : float
        Label noise: each resolved event outcome is flipped with this probability.
    softness : float
        If > 0, an event succeeds with probability ``sigmoid(signed_distance / softness)``
        instead of the sharp indicator (a smooth ground-truth probability, for calibration
        tests).
    seed : int
        Seed of the label noise.
    """

    dimension: int
    events: Mapping[str, OracleEvent]
    invalid_balls: tuple[tuple[tuple[float, ...], float], ...] = ()
    flip_probability: float = 0.0
    softness: float = 0.0
    seed: int = 0
    event_parents: Mapping[str, tuple[str, ...]] = field(init=False, repr=False)
    any_joins: frozenset[str] = field(init=False, repr=False)

    def __post_init__(self):
        parents = {name: tuple(ev.parents) for name, ev in self.events.items()}
        topological_events(parents)  # validates the graph
        for name, ev in self.events.items():
            if ev.join not in ("all", "any"):
                raise ValueError(f"event {name!r}: join {ev.join!r}; allowed: all, any")
        object.__setattr__(self, "any_joins", frozenset(
            name for name, ev in self.events.items() if ev.join == "any"))
        for name, ev in self.events.items():
            if ev.region is not None:
                n_reg = ev.region.dimension
                if n_reg != len(ev.dims):
                    raise ValueError(
                        f"event {name!r}: region has {n_reg} dimensions but dims={ev.dims}"
                    )
            if any(not 0 <= j < self.dimension for j in ev.dims):
                raise ValueError(f"event {name!r}: dims {ev.dims} outside 0..{self.dimension - 1}")
        object.__setattr__(self, "event_parents", parents)

    @property
    def event_dimensions(self) -> dict[str, tuple[int, ...]]:
        """Each event's own dimensions (its true subspace): the causal graph's answer."""
        return {name: tuple(ev.dims) for name, ev in self.events.items()}

    # --- ground truth ------------------------------------------------------------------------

    def success_probability(self, X: np.ndarray) -> dict[str, np.ndarray]:
        """True P(event succeeds | parents succeeded, x) per event, each (n,)."""
        X = np.atleast_2d(np.asarray(X, dtype=float))
        out = {}
        for name, ev in self.events.items():
            if ev.region is None:
                p = np.ones(len(X))
            else:
                sd = ev.region.signed_distance(X[:, list(ev.dims)])
                if self.softness > 0:
                    p = 1.0 / (1.0 + np.exp(-sd / self.softness))
                else:
                    p = (sd >= 0).astype(float)
            out[name] = (1 - self.flip_probability) * p + self.flip_probability * (1 - p)
        return out

    def global_probability(self, X: np.ndarray) -> np.ndarray:
        """True P(the whole graph succeeds | x), (n,): the product over events, or with
        any-joins the graph's success formula (:class:`~.graph.SuccessLogic`)."""
        probs = self.success_probability(X)
        if self.any_joins:
            return SuccessLogic(self.event_parents, self.any_joins).probability(probs)
        return np.prod(np.stack(list(probs.values())), axis=0)

    def event_signed_distance(self, name: str, X: np.ndarray) -> np.ndarray:
        """(n,) distance of each row to event ``name``'s region boundary (+ inside)."""
        ev = self.events[name]
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if ev.region is None:
            return np.full(len(X), np.inf)
        return ev.region.signed_distance(X[:, list(ev.dims)])

    # --- Problem protocol ---------------------------------------------------------------------

    def penetration(self, x: np.ndarray) -> float:
        """Depth of ``x`` inside the deepest invalid ball, 0 when valid."""
        x = np.asarray(x, dtype=float).reshape(-1)
        depth = 0.0
        for centre, radius in self.invalid_balls:
            depth = max(depth, radius - float(np.linalg.norm(x - np.asarray(centre))))
        return depth

    def validity(self, X: np.ndarray) -> np.ndarray:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        valid = np.ones(len(X), dtype=bool)
        for centre, radius in self.invalid_balls:
            valid &= np.linalg.norm(X - np.asarray(centre), axis=1) >= radius
        return valid

    def simulate(self, X: np.ndarray) -> list[Label]:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        valid = self.validity(X)
        probs = self.success_probability(X)
        names = list(self.events)
        order = topological_events(self.event_parents)
        has_child = {p for ps in self.event_parents.values() for p in ps}
        leaves = [e for e in names if e not in has_child]
        labels = []
        for i, x in enumerate(X):
            if not valid[i]:
                labels.append(Label(False, False, {e: None for e in names}))
                continue
            u = self._uniforms(x, len(order))
            state: dict[str, bool | None] = {}
            for k, e in enumerate(order):
                woke = [state[p] is True for p in self.event_parents[e]]
                if any(woke) if e in self.any_joins else all(woke):
                    state[e] = bool(u[k] < probs[e][i])
                else:
                    state[e] = None
            events = {e: state[e] for e in names}
            labels.append(Label(True, all(events[e] is True for e in leaves), events))
        return labels

    def _uniforms(self, x: np.ndarray, n: int) -> np.ndarray:
        """n uniforms that depend only on (seed, x): deterministic label noise."""
        digest = hashlib.blake2b(np.ascontiguousarray(x, dtype=float).tobytes(), digest_size=16)
        words = np.frombuffer(digest.digest(), dtype=np.uint32)
        return np.random.default_rng([self.seed, *words.tolist()]).random(n)


def chain_oracle(d: int, width: float, seed: int) -> ProductOracle:
    """A synthetic machine of ``d // 2`` events in a row: event k happens when coordinates
    2k and 2k + 1 fall in a box of side ``width`` placed at random (seed ``seed``), and only
    after event k - 1. The structure a real chain's parameters mostly have (each event
    depends on the parts it moves), stripped of everything else."""
    rng = np.random.default_rng(1000 + seed)
    events, parents = {}, ()
    for k in range(d // 2):
        low = rng.uniform(0.0, 1.0 - width, 2)
        events[f"e{k}"] = OracleEvent(parents, (2 * k, 2 * k + 1),
                                      BoxRegion(tuple(low), tuple(low + width)))
        parents = (f"e{k}",)
    return ProductOracle(d, events)
