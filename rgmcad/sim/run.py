"""One simulation of one layout, watched by the causal graph; the result is a value.

A layout whose bodies intersect at the start is ``invalid`` and is not simulated. Otherwise
the world is built, and at every ``t = i * dt`` the awake events are evaluated before the
physics step; the run stops as soon as the causal graph is resolved, or at the scenario's
maximum duration (events still awake then are left awake and the outcome is a failure).

Outcomes and event states are enums whose values are the words written to results files.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from rgmcad.parts.store import BuiltPart
from rgmcad.scene.bodies import make_scene
from rgmcad.scene.model import Scenario
from rgmcad.sim.cache import PartCache
from rgmcad.sim.causal import CausalGraph, EventState
from rgmcad.sim.engine import Engine
from rgmcad.sim.events import make_condition
from rgmcad.sim.validity import TOLERANCE, Validity, check_validity
from rgmcad.sim.world import World


class Outcome(StrEnum):
    """How a simulation ended; its value is the word results files use."""

    SUCCESS = "success"
    FAILURE = "failure"
    INVALID = "invalid"


@dataclass(frozen=True)
class EventRecord:
    name: str
    state: EventState
    time: float | None  # s, when it succeeded or failed


@dataclass(frozen=True)
class SimulationResult:
    outcome: Outcome
    events: tuple[EventRecord, ...]  # in the scenario's event order
    sim_time: float  # simulated seconds
    wall_time: float  # seconds, validity test included
    step_time: float = 0.0  # seconds spent inside the physics steps
    validity: Validity | None = None
    validity_time: float = 0.0  # seconds in the validity test
    build_time: float = 0.0  # seconds building the world and the event conditions

    @property
    def n_success(self) -> int:
        return sum(e.state is EventState.SUCCESS for e in self.events)

    def labels(self) -> dict[str, bool | None]:
        """Per event: True success, False failure, None never resolved."""
        return {e.name: _LABELS.get(e.state) for e in self.events}

    def to_dict(self) -> dict:
        out = {
            "outcome": self.outcome.value,
            "events": [{"name": e.name, "state": e.state.value, "time": e.time}
                       for e in self.events],
            "successful_events": self.n_success,
            "sim_time": self.sim_time,
            "wall_time": self.wall_time,
        }
        if self.validity is not None and not self.validity.valid:
            out["overlaps"] = [{"first": o.first, "second": o.second, "depth": o.depth}
                               for o in self.validity.overlaps]
        return out


_LABELS = {EventState.SUCCESS: True, EventState.FAILURE: False}

Observer = Callable[[World, float], None]


def simulate(scenario: Scenario, values, parts: Mapping[str, BuiltPart], *,
             check: bool = True, tolerance: float = TOLERANCE,
             observer: Observer | None = None, observe_every: int = 1,
             engine: Engine | None = None, cache: PartCache | None = None) -> SimulationResult:
    """Simulate the layout with real parameter ``values`` (d,).

    Parameters
    ----------
    parts : built parts by object name (:func:`rgmcad.scene.bodies.load_parts`).
    check : run the validity test first (an invalid layout is not simulated).
    observer : called as ``observer(world, t)`` every ``observe_every`` steps and at the end
        (for rendering; leave None for speed).
    engine, cache : reused by a caller that simulates many layouts (see
        :class:`~rgmcad.sim.world.World`); None: the simulation's own.
    """
    start = time.perf_counter()
    scene = make_scene(scenario, np.asarray(values, float), parts)
    validity = None
    if check:
        validity = check_validity(scene, tolerance, cache=cache)
        if not validity.valid:
            events = tuple(EventRecord(n, EventState.ASLEEP, None) for n in scenario.events)
            elapsed = time.perf_counter() - start
            return SimulationResult(Outcome.INVALID, events, 0.0, elapsed, 0.0, validity,
                                    elapsed)
    built_at = time.perf_counter()
    settings = scenario.settings
    with World(scene, settings, engine, cache) as world:
        graph = CausalGraph(
            scenario.events,
            {name: make_condition(spec, world) for name, spec in scenario.events.items()},
            settings.event_timeout,
        )
        ready_at = time.perf_counter()
        dt = settings.timestep
        n_steps = int(round(settings.duration / dt))
        step_time = 0.0
        t = 0.0
        clock = time.perf_counter
        step = world.step
        for i in range(n_steps + 1):
            t = i * dt
            if graph.update(t):
                break
            if observer is not None and i % observe_every == 0:
                observer(world, t)
            if i == n_steps:
                break
            t0 = clock()
            step()
            step_time += clock() - t0
        if observer is not None:
            observer(world, t)
    outcome = Outcome.SUCCESS if graph.resolved and graph.succeeded() else Outcome.FAILURE
    events = tuple(EventRecord(n, graph.state[n], graph.time[n]) for n in scenario.events)
    return SimulationResult(outcome, events, t, clock() - start, step_time, validity,
                            built_at - start, ready_at - built_at)
