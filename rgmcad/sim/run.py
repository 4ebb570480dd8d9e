"""One simulation of one layout, watched by the causal graph; the result is a value.

A layout whose bodies intersect at the start is ``invalid`` and is not simulated. Otherwise
the world is built, and at every ``t = i * dt`` the awake events are evaluated before the
physics step; the run stops as soon as the causal graph is resolved, or at the scenario's
maximum duration (events still awake then are left awake and the outcome is a failure).

Outcomes and event states are enums whose values are the words written to results files.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from rgmcad.geometry import hpr_of
from rgmcad.parts.store import BuiltPart
from rgmcad.scene.bodies import Scene, make_scene
from rgmcad.scene.model import Scenario
from rgmcad.scene.perturbation import PLACEMENT_SCALES, PhysicsDraw, hand_placed_objects
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
    steps: int = 0  # physics steps taken
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
StepHook = Callable[[World, float], None]


def simulate(scenario: Scenario, values, parts: Mapping[str, BuiltPart], *,
             check: bool = True, tolerance: float = TOLERANCE,
             observer: Observer | None = None, observe_every: int = 1,
             engine: Engine | None = None, cache: PartCache | None = None,
             hooks: Sequence[StepHook] = (),
             physics: PhysicsDraw | None = None) -> SimulationResult:
    """Simulate the layout with real parameter ``values`` (d,).

    Parameters
    ----------
    parts : built parts by object name (:func:`rgmcad.scene.bodies.load_parts`).
    check : run the validity test first (an invalid layout is not simulated); False for a
        layout already known valid.
    observer : called as ``observer(world, t)`` every ``observe_every`` steps and at the end
        (for rendering; leave None for speed); ``observe_every = 0``: at the end only, with
        nothing added to the step loop.
    engine, cache : reused by a caller that simulates many layouts (see
        :class:`~rgmcad.sim.world.World`); None: the simulation's own.
    hooks : called as ``hook(world, t)`` before every physics step, after the events
        (recording, constraints solved between steps); none costs nothing.
    physics : a draw of physical properties (friction, mass, restitution) applied to the
        scene after the validity test, which does not depend on them; None: the scenario's.
    """
    start = time.perf_counter()
    scene = make_scene(scenario, np.asarray(values, float), parts)
    validity = None
    if check:
        validity = check_validity(scene, tolerance, cache=cache)
        if not validity.valid:
            events = tuple(EventRecord(n, EventState.ASLEEP, None) for n in scenario.events)
            elapsed = time.perf_counter() - start
            return SimulationResult(Outcome.INVALID, events, 0.0, elapsed, validity=validity,
                                    validity_time=elapsed)
    if physics is not None:
        if physics.ranges.moves_parts:
            scene = _placed_by_hand(scenario, values, parts, physics, scene, tolerance, cache)
        scene = physics.apply(scene)
    built_at = time.perf_counter()
    settings = scenario.settings
    if observer is not None and observe_every:
        hooks = (*hooks, _every(observer, observe_every))
    with World(scene, settings, engine, cache) as world:
        graph = CausalGraph(
            scenario.events,
            {name: make_condition(spec, world) for name, spec in scenario.events.items()},
            settings.event_timeout,
        )
        ready_at = time.perf_counter()
        t, steps = _run(world, graph, settings, tuple(hooks))
        if observer is not None:
            observer(world, t)
    outcome = Outcome.SUCCESS if graph.resolved and graph.succeeded() else Outcome.FAILURE
    events = tuple(EventRecord(n, graph.state[n], graph.time[n]) for n in scenario.events)
    return SimulationResult(outcome, events, t, time.perf_counter() - start, steps, validity,
                            built_at - start, ready_at - built_at)


def final_poses(into: dict) -> dict:
    """Keyword arguments of :func:`simulate` that leave in ``into`` each body's pose in the
    world when the run stops: ``{body: {x, y, z (m), heading, pitch, roll (deg)}}``, as a
    layout file writes a pose (``rgmcad simulate --json``'s ``final_poses``)."""
    def observe(world, t):  # called once, when the run has stopped
        for name in world.handles:
            m = world.pose(name)
            h, p, r = hpr_of(m[:3, :3])
            into[name] = {"x": float(m[0, 3]), "y": float(m[1, 3]), "z": float(m[2, 3]),
                          "heading": float(h), "pitch": float(p), "roll": float(r)}

    return {"observer": observe, "observe_every": 0}


def _placed_by_hand(scenario, values, parts, physics: PhysicsDraw, designed: Scene,
                    tolerance: float, cache) -> Scene:
    """The layout as a hand places it under ``physics``: every hand-placed object at its
    draw; objects whose bodies intersect drawn again (smaller and smaller, at last where
    designed) until nothing does."""
    movable = hand_placed_objects(scenario, [n for n, p in parts.items() if p.infinite])
    if physics.moved is not None:
        movable = [name for name in movable if name in physics.moved]
    placed = set(movable)
    attempts = dict.fromkeys(movable, 0)
    last = len(PLACEMENT_SCALES) - 1
    values = np.asarray(values, float)
    while True:
        scene = make_scene(scenario, values, parts, physics.offsets(movable, attempts))
        validity = check_validity(scene, tolerance, cache=cache)
        if validity.valid:
            return scene
        involved = set()
        for overlap in validity.overlaps:
            movers = {_placed_owner(scenario, scene, body, placed)
                      for body in (overlap.first, overlap.second)} - {None}
            involved |= movers or placed  # a rope's path: every object drawn again
        involved = {name for name in involved if attempts[name] < last}
        if not involved:
            return designed
        for name in involved:
            attempts[name] += 1


def _placed_owner(scenario, scene: Scene, body: str, placed: set[str]) -> str | None:
    """The hand-placed object that moved ``body`` (its object or nearest such ancestor)."""
    name = scene.bodies[body].object if body in scene.bodies else None
    while name is not None and name not in placed:
        name = scenario.objects[name].parent
    return name


def _every(observer: Observer, every: int) -> StepHook:
    """A hook calling ``observer`` before steps 0, every, 2 every, ..."""
    calls = itertools.count()
    every = max(int(every), 1)

    def hook(world, t):
        if next(calls) % every == 0:
            observer(world, t)

    return hook


def _run(world: World, graph: CausalGraph, settings, hooks: tuple) -> tuple[float, int]:
    """The step loop: at ``t = i * dt`` the awake events, then the hooks, then a physics
    step; until the graph is resolved or the duration is over. Returns (t, steps taken)."""
    dt = settings.timestep
    n_steps = int(round(settings.duration / dt))
    update, step = graph.update, world.stepper()
    t = 0.0
    for i in range(n_steps + 1):
        t = world.time = i * dt
        if update(t):
            return t, i
        for hook in hooks:
            hook(world, t)
        if i == n_steps:
            break
        step()
    return t, n_steps
