"""The causal graph at run time: events sleep, wake, succeed or fail as the simulation runs.

* Every event starts asleep. The root wakes at t = 0; any other event wakes when all its
  parents have succeeded (``join = "all"``, the default) or when any has (``join = "any"``).
  A child can wake and succeed in the same step as its parent.
* An awake event succeeds when its condition holds (for ``hold`` seconds in a row, if given),
  and fails when it has been awake for more than its timeout (2 s by default) without that.
  Success and failure are final. ``negate = true`` only swaps the condition for its negation
  (:func:`rgmcad.sim.events.make_condition`): the event succeeds once the condition is false.
* ``negate = "always"`` (:attr:`~rgmcad.scene.eventspec.Negation.ALWAYS`) turns this around: the
  condition must never hold (for ``hold`` seconds in a row) while the event is awake. The
  event fails at the step it does, and succeeds, waking its children, at the first step more
  than its timeout after it woke. Its condition is the plain, un-negated one.
* The graph is *resolved* when no event is awake: nothing can change any more. The
  simulation stops there. The outcome is a success when every leaf event (one with no
  children) succeeded. With all-joins this means every event succeeded; with an any-join, a
  failed alternative does not fail the graph when another parent carried the chain on.

The paper's code declared failure as soon as no event was awake and one had failed; that
cannot express alternatives, which its authors listed as future work.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from enum import StrEnum

from rgmcad.scene.eventspec import Negation
from rgmcad.scene.model import EventSpec


class EventState(StrEnum):
    """Where an event stands; its value is the word results files use."""

    ASLEEP = "asleep"
    AWAKE = "awake"
    SUCCESS = "success"
    FAILURE = "failure"


ASLEEP, AWAKE, SUCCESS, FAILURE = EventState


class CausalGraph:
    """Run-time states of a scenario's events.

    Parameters
    ----------
    events : the scenario's event specs (a DAG with one root), in any order.
    conditions : the condition of each event (see :mod:`rgmcad.sim.events`).
    default_timeout : seconds an event may stay awake (when its spec gives none).
    """

    def __init__(self, events: Mapping[str, EventSpec],
                 conditions: Mapping[str, Callable[[], bool]], default_timeout: float):
        self.specs = dict(events)
        self.conditions = dict(conditions)
        self.children: dict[str, list[str]] = {n: [] for n in events}
        for name, spec in events.items():
            for parent in spec.after:
                self.children[parent].append(name)
        self.timeouts = {n: (s.timeout if s.timeout is not None else default_timeout)
                         for n, s in events.items()}
        self.holds = {n: s.hold for n, s in events.items()}
        # events whose condition must never hold: holding fails them, the timeout succeeds
        self.never = {n for n, s in events.items() if s.negate is Negation.ALWAYS}
        self.state: dict[str, EventState] = dict.fromkeys(events, ASLEEP)
        self.time: dict[str, float | None] = dict.fromkeys(events)  # of success or failure
        self.woke: dict[str, float] = {}
        self._true_since: dict[str, float] = {}
        self.awake: list[str] = []
        # what a sweep reads of each awake event, rebuilt as events wake and finish
        self._watch: tuple[tuple[str, Callable[[], bool], float, float], ...] = ()
        self.root = next(n for n, s in events.items() if not s.after)
        self.started = False

    @property
    def resolved(self) -> bool:
        return self.started and not self.awake

    def update(self, t: float) -> bool:
        """Evaluate the awake events at time ``t`` (s). Returns True once resolved.

        Runs before every physics step, so the usual case (an awake event whose condition
        does not hold and whose timeout is not reached) is handled inline."""
        if not self.started:  # the root and whatever it wakes are evaluated as they wake
            self.started = True
            self._wake(self.root, t)
            return not self.awake
        true_since = self._true_since
        # over a snapshot: events woken during the sweep were evaluated as they woke, and only
        # its own evaluation finishes an event
        for name, condition, woke, timeout in self._watch:
            holds = condition()
            if holds or name in true_since or t - woke > timeout:
                self._apply(name, t, holds)
        return not self.awake

    def _rewatch(self) -> None:
        self._watch = tuple((n, self.conditions[n], self.woke[n], self.timeouts[n])
                            for n in self.awake)

    def _wake(self, name: str, t: float) -> None:
        self.state[name] = AWAKE
        self.woke[name] = t
        self.awake.append(name)
        self._rewatch()
        self._apply(name, t, self.conditions[name]())

    def _apply(self, name: str, t: float, holds: bool) -> None:
        """An awake event's step, its condition found to hold or not at ``t``."""
        if holds:
            since = self._true_since.setdefault(name, t)
            if t - since >= self.holds[name]:
                if name in self.never:
                    self._finish(name, FAILURE, t)
                else:
                    self._succeed(name, t)
                return
        else:
            self._true_since.pop(name, None)
        if t - self.woke[name] > self.timeouts[name]:
            if name in self.never:
                self._succeed(name, t)
            else:
                self._finish(name, FAILURE, t)

    def _succeed(self, name: str, t: float) -> None:
        self._finish(name, SUCCESS, t)
        for child in self.children[name]:
            if self.state[child] is ASLEEP and self._ready(child):
                self._wake(child, t)

    def _ready(self, name: str) -> bool:
        parents = [self.state[p] is SUCCESS for p in self.specs[name].after]
        return any(parents) if self.specs[name].join == "any" else all(parents)

    def _finish(self, name: str, state: EventState, t: float) -> None:
        self.state[name] = state
        self.time[name] = t
        self.awake.remove(name)
        self._rewatch()

    def succeeded(self) -> bool:
        """True when every leaf event succeeded."""
        return all(self.state[n] is SUCCESS for n, kids in self.children.items() if not kids)
