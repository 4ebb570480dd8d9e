"""A scenario as a learning :class:`~rgmcad.learning.oracles.Problem`: the design space
``[0, 1]^d``, the exact validity test and the simulator.

:class:`ScenarioProblem` holds only the scenario file and the part cache folder, so it pickles
in a few hundred bytes; the scenario and its built parts are loaded lazily, once per process
(:func:`context`), which is what a worker pool needs. Every simulation is reported as a
:class:`SimRecord` (outcome, per-event label and time, seconds spent), from which the learner's
:class:`~rgmcad.learning.oracles.Label` follows. Importing this module does not import the
learner (scikit-learn alone takes 3 s to import), so pool workers start fast.

The causal graph handed to the learner is the scenario's: ``event_parents`` (each event's
``after``) and ``any_joins`` (the events with ``join = "any"``).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rgmcad.parts.build import DEFAULT_BUILD_DIR

__all__ = ["SimRecord", "ScenarioProblem", "context", "scenario_digest", "event_parents", "any_joins"]


@dataclass(frozen=True)
class SimRecord:
    """One finished simulation (a plain value, cheap to pickle and to store as JSON).

    Attributes
    ----------
    valid : bool
        False when the initial layout penetrates (it was then not simulated).
    outcome : str
        ``"success"``, ``"failure"`` or ``"invalid"``.
    events : Mapping[str, tuple[bool | None, float | None]]
        Per event (scenario order): the label (True success, False failure, None never
        resolved) and the time (s) it resolved at.
    seconds : float
        Wall time of the simulation, validity test included.
    """

    valid: bool
    outcome: str
    events: Mapping[str, tuple[bool | None, float | None]]
    seconds: float

    def label(self):
        """The learner's view of this simulation (a :class:`~rgmcad.learning.oracles.Label`)."""
        from rgmcad.learning.oracles import Label  # here: workers need not import scikit-learn

        return Label(self.valid, self.outcome == "success",
                     {e: lab for e, (lab, _) in self.events.items()})

    def to_json(self) -> dict:
        return {"valid": self.valid, "outcome": self.outcome,
                "events": {e: [lab, t] for e, (lab, t) in self.events.items()},
                "seconds": self.seconds}

    @classmethod
    def from_json(cls, data: Mapping) -> SimRecord:
        events = {e: (v[0], v[1]) for e, v in data["events"].items()}
        return cls(bool(data["valid"]), str(data["outcome"]), events, float(data["seconds"]))


def scenario_digest(path: str | Path) -> str:
    """SHA-256 of the scenario file's bytes (identifies the scenario a run was made for)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def event_parents(scenario) -> dict[str, tuple[str, ...]]:
    """Each event of the scenario's causal graph and the events it waits for."""
    return {name: tuple(ev.after) for name, ev in scenario.events.items()}


def any_joins(scenario) -> frozenset[str]:
    """The events that wake when any of their parents succeeded."""
    return frozenset(name for name, ev in scenario.events.items() if ev.join == "any")


_CONTEXTS: dict[tuple[str, str], tuple[object, dict]] = {}
_TESTERS: dict[tuple[str, str], object] = {}  # LayoutValidity per process and context


def context(scenario_path: str, build_dir: str):
    """``(scenario, parts)`` loaded once per process and per (scenario file, part folder).

    Builds missing parts (CadQuery) the first time; a worker pool's initializer calls this so
    that the first task does not pay for it.
    """
    key = (scenario_path, build_dir)
    if key not in _CONTEXTS:
        from rgmcad.scene.scenario import load_scenario
        from rgmcad.scene.bodies import load_parts

        scenario = load_scenario(scenario_path)
        _CONTEXTS[key] = (scenario, load_parts(scenario, Path(build_dir)))
    return _CONTEXTS[key]


@dataclass(frozen=True, eq=False)
class ScenarioProblem:
    """The :class:`~rgmcad.learning.oracles.Problem` of a scenario file.

    Parameters
    ----------
    scenario_path : str or Path
        The scenario (TOML).
    build_dir : str or Path
        The part cache (parts are built there if missing).

    Attributes
    ----------
    dimension : int
        d.
    event_parents : Mapping[str, tuple[str, ...]]
        The causal graph (see :func:`event_parents`).
    any_joins : frozenset of str
        Its events with ``join = "any"``.
    """

    scenario_path: str
    build_dir: str = str(DEFAULT_BUILD_DIR)
    dimension: int = field(init=False)
    event_parents: Mapping[str, tuple[str, ...]] = field(init=False)
    any_joins: frozenset[str] = field(init=False)

    def __post_init__(self):
        object.__setattr__(self, "scenario_path", str(Path(self.scenario_path).resolve()))
        object.__setattr__(self, "build_dir", str(Path(self.build_dir).resolve()))
        scenario = self.scenario
        object.__setattr__(self, "dimension", scenario.dimension)
        object.__setattr__(self, "event_parents", event_parents(scenario))
        object.__setattr__(self, "any_joins", any_joins(scenario))

    def __getstate__(self):
        return {"scenario_path": self.scenario_path, "build_dir": self.build_dir,
                "dimension": self.dimension, "event_parents": dict(self.event_parents),
                "any_joins": self.any_joins}

    def __setstate__(self, state):
        for k, v in state.items():
            object.__setattr__(self, k, v)

    @property
    def scenario(self):
        """The loaded :class:`~rgmcad.scene.scenario.Scenario` (cached per process)."""
        return context(self.scenario_path, self.build_dir)[0]

    @property
    def parts(self) -> dict:
        """Built parts by object name (cached per process)."""
        return context(self.scenario_path, self.build_dir)[1]

    def values(self, x) -> np.ndarray:
        """Real parameter values (d,) of a design vector (d,)."""
        from rgmcad.scene.design_space import values_from_vector

        return values_from_vector(self.scenario, np.asarray(x, dtype=float))

    def _validity(self, x):
        from rgmcad.scene.bodies import make_scene
        from rgmcad.sim.validity import check_validity

        return check_validity(make_scene(self.scenario, self.values(x), self.parts))

    # --- Problem protocol -----------------------------------------------------------------

    def validity(self, X: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each row of ``X`` (n, d) is physically valid (the exact test of
        :func:`~rgmcad.sim.validity.check_validity`, run on all rows at once)."""
        from rgmcad.scene.design_space import bounds

        X = np.atleast_2d(np.asarray(X, dtype=float))
        key = (self.scenario_path, self.build_dir)
        if key not in _TESTERS:
            from rgmcad.sim.validity import LayoutValidity

            _TESTERS[key] = LayoutValidity(self.scenario, self.parts)
        low, high = bounds(self.scenario)
        return _TESTERS[key](low + X * (high - low))

    def penetration(self, x: np.ndarray) -> float:
        """Summed penetration depth (m) beyond the validity tolerance; 0 iff valid."""
        return float(self._validity(np.asarray(x, dtype=float).reshape(-1)).penetration)

    def simulate(self, X: np.ndarray) -> list:
        """One :class:`Label` per row of ``X`` (n, d), in order."""
        return [r.label() for r in self.simulate_records(X)]

    # --- richer outputs ----------------------------------------------------------------------

    def simulate_records(self, X: np.ndarray | Sequence) -> list[SimRecord]:
        """Simulate each row of ``X`` (n, d); one :class:`SimRecord` per row, in order."""
        return [self.simulate_one(x) for x in np.atleast_2d(np.asarray(X, dtype=float))]

    def simulate_one(self, x: np.ndarray) -> SimRecord:
        """Simulate the design vector ``x`` (d,) (the validity test included)."""
        from rgmcad.sim.run import simulate

        r = simulate(self.scenario, self.values(x), self.parts)
        labels = r.labels()
        events = {e.name: (labels[e.name], e.time) for e in r.events}
        return SimRecord(r.outcome.value != "invalid", r.outcome.value, events, float(r.wall_time))
