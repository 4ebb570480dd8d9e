"""A scenario as a learning :class:`~rgmcad.learning.oracles.Problem`: the design space
``[0, 1]^d``, the exact validity test and the simulator.

What simulating a scenario takes in one process (the scenario, its built parts, the data
derived from them, the many-layout validity test and a physics engine) is a
:class:`ScenarioContext`, loaded once and reused for every layout. :class:`ScenarioProblem`
holds only the scenario file and the part folder, so it pickles in a few hundred bytes, and
loads its context on first use; its :meth:`~ScenarioProblem.context` is what a worker pool's
initializer runs, once per worker (:mod:`rgmcad.runs.executor`), and tasks such as
:func:`simulate_task` get that context as their first argument. Every simulation is reported
as a :class:`SimRecord` (outcome, per-event label and time, seconds spent), from which the
learner's :class:`~rgmcad.learning.oracles.Label` follows. Importing this module does not
import the learner (scikit-learn alone takes 3 s to import), so pool workers start fast.

The causal graph handed to the learner is the scenario's: ``event_parents`` (each event's
``after``) and ``any_joins`` (the events with ``join = "any"``).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.sim.run import Outcome

__all__ = ["SimRecord", "ScenarioContext", "ScenarioProblem", "ContextPayload", "simulate_task",
           "simulate_layout_task", "simulate_values_task", "worst_of", "validity_task",
           "scenario_digest", "event_parents", "any_joins", "event_dimensions"]


@dataclass(frozen=True)
class SimRecord:
    """One finished simulation (a plain value, cheap to pickle and to store as JSON).

    Attributes
    ----------
    valid : bool
        False when the initial layout penetrates (it was then not simulated).
    outcome : Outcome
        Stored as its value: ``"success"``, ``"failure"`` or ``"invalid"``.
    events : Mapping[str, tuple[bool | None, float | None]]
        Per event (scenario order): the label (True success, False failure, None never
        resolved) and the time (s) it resolved at.
    seconds : float
        Wall time of the simulation, validity test included.
    """

    valid: bool
    outcome: Outcome
    events: Mapping[str, tuple[bool | None, float | None]]
    seconds: float

    def label(self):
        """The learner's view of this simulation (a :class:`~rgmcad.learning.oracles.Label`)."""
        from rgmcad.learning.oracles import Label  # here: workers need not import scikit-learn

        return Label(self.valid, self.outcome is Outcome.SUCCESS,
                     {e: lab for e, (lab, _) in self.events.items()})

    def to_json(self) -> dict:
        return {"valid": self.valid, "outcome": self.outcome.value,
                "events": {e: [lab, t] for e, (lab, t) in self.events.items()},
                "seconds": self.seconds}

    @classmethod
    def from_json(cls, data: Mapping, events: Sequence[str] | None = None) -> SimRecord:
        """The record of a stored line, checked: ValueError, saying what is wrong, for
        anything :meth:`to_json` cannot have written (a missing key, a wrong type, an
        outcome that contradicts ``valid``, events other than ``events`` when given)."""
        if not isinstance(data, Mapping):
            raise ValueError(f"expected a JSON object, got {type(data).__name__}")
        missing = [k for k in ("valid", "outcome", "events", "seconds") if k not in data]
        if missing:
            raise ValueError(f"missing {', '.join(missing)}")
        valid, outcome, stored = data["valid"], data["outcome"], data["events"]
        if not isinstance(valid, bool):
            raise ValueError(f"valid: expected true or false, got {valid!r}")
        if outcome not in [o.value for o in Outcome] or (outcome == "invalid") == valid:
            raise ValueError(f"outcome: {outcome!r} with valid {valid}")
        if not isinstance(stored, Mapping) or (events is not None and set(stored) != set(events)):
            raise ValueError("events: not the scenario's events")
        out = {}
        for e, v in stored.items():
            if not (isinstance(v, list) and len(v) == 2 and (v[0] is None or v[0] is True
                    or v[0] is False) and (v[1] is None or _finite(v[1]))):
                raise ValueError(f"events.{e}: expected [label, time], got {v!r}")
            out[e] = (v[0], v[1])
        if not (_finite(data["seconds"]) and data["seconds"] >= 0):
            raise ValueError(f"seconds: {data['seconds']!r}")
        return cls(valid, Outcome(outcome), out, float(data["seconds"]))


def _finite(v) -> bool:
    """A JSON number (not a boolean), finite."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def scenario_digest(path: str | Path) -> str:
    """SHA-256 of the scenario file's bytes (identifies the scenario a run was made for)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def event_parents(scenario) -> dict[str, tuple[str, ...]]:
    """Each event of the scenario's causal graph and the events it waits for."""
    return {name: tuple(ev.after) for name, ev in scenario.events.items()}


def event_dimensions(scenario) -> dict[str, tuple[int, ...]]:
    """Each event's coordinates: the free parameters that move the objects it names, a
    parameter of the object itself or of one it is posed on (a domino's run, a ball's
    track). What the staged exploration keeps once the event happened."""
    def posed_on(name):
        while name is not None:
            yield name
            name = scenario.objects[name].parent

    out = {}
    for event, spec in scenario.events.items():
        moved = {o for obj in spec.objects.values() if obj in scenario.objects for o in posed_on(obj)}
        out[event] = tuple(i for i, f in enumerate(scenario.free) if f.object in moved)
    return out


def any_joins(scenario) -> frozenset[str]:
    """The events that wake when any of their parents succeeded."""
    return frozenset(name for name, ev in scenario.events.items() if ev.join == "any")


class ScenarioContext:
    """Everything simulating layouts of one scenario takes in one process, loaded once.

    Owns a physics engine (connected at the first simulation) and the data derived from the
    parts (:class:`~rgmcad.sim.cache.PartCache`); neither changes a result, only its cost.

    Parameters
    ----------
    scenario : Scenario
    parts : Mapping[str, BuiltPart]
        Its built parts by object name.
    """

    def __init__(self, scenario, parts: Mapping):
        from rgmcad.scene.design_space import bounds
        from rgmcad.sim.cache import PartCache

        self.scenario = scenario
        self.parts = parts
        self.cache = PartCache()
        self.low, self.high = bounds(scenario)
        self._engine = None
        self._tester = None

    @classmethod
    def load(cls, scenario_path: str | Path, build_dir: str | Path = DEFAULT_BUILD_DIR,
             parts_dir: str | Path | None = None):
        """The context of a scenario file, its part families from ``parts_dir`` (default: the
        shipped ones); missing parts are built (CadQuery) into ``build_dir``."""
        from rgmcad.scene.bodies import load_parts
        from rgmcad.scene.loader import load_scenario

        scenario = load_scenario(scenario_path, parts_dir=parts_dir)
        return cls(scenario, load_parts(scenario, Path(build_dir)))

    def values(self, x) -> np.ndarray:
        """Real parameter values (d,) of a design vector (d,)."""
        from rgmcad.scene.design_space import values_from_vector

        return values_from_vector(self.scenario, np.asarray(x, dtype=float))

    def validity(self, X: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each row of ``X`` (n, d) is physically valid (the exact test of
        :func:`~rgmcad.sim.validity.check_validity`, run on all rows at once)."""
        if self._tester is None:
            from rgmcad.sim.layout_validity import LayoutValidity

            self._tester = LayoutValidity(self.scenario, self.parts, cache=self.cache)
        X = np.atleast_2d(np.asarray(X, dtype=float))
        return self._tester(self.low + X * (self.high - self.low))

    def check(self, x):
        """The full :class:`~rgmcad.sim.validity.Validity` of the design vector ``x`` (d,)."""
        from rgmcad.scene.bodies import make_scene
        from rgmcad.sim.validity import check_validity

        return check_validity(make_scene(self.scenario, self.values(x), self.parts),
                              cache=self.cache)

    def simulate_one(self, x: np.ndarray, known_valid: bool = False,
                     physics=None) -> SimRecord:
        """Simulate the design vector ``x`` (d,), after the validity test unless the caller
        already knows the layout is valid (``known_valid``: the result is the same), with the
        physical properties of ``physics`` (a :class:`~rgmcad.scene.perturbation.PhysicsDraw`;
        None: the scenario's)."""
        return self.simulate_values(self.values(x), check=not known_valid, physics=physics)

    def simulate_values(self, values: np.ndarray, check: bool = True,
                        physics=None) -> SimRecord:
        """Simulate the layout of real parameter ``values`` (d,) exactly as given (as
        ``rgmcad simulate --value`` does), the validity test included unless ``check`` is
        False; ``physics`` as in :meth:`simulate_one`."""
        from rgmcad.sim.run import simulate

        if self._engine is None:
            from rgmcad.sim.engine import Engine

            self._engine = Engine(renderer=False)
        r = simulate(self.scenario, np.asarray(values, float), self.parts, check=check,
                     engine=self._engine, cache=self.cache, physics=physics)
        labels = r.labels()
        events = {e.name: (labels[e.name], e.time) for e in r.events}
        return SimRecord(r.outcome is not Outcome.INVALID, r.outcome, events,
                         float(r.wall_time))

    def close(self) -> None:
        """Disconnect the engine and drop the derived data."""
        if self._engine is not None:
            self._engine.close()
            self._engine = None
        self.cache.close()


@dataclass(frozen=True, eq=False)
class ContextPayload:
    """What a machine without the client's files needs to build a :class:`ScenarioContext`:
    the scenario's text and file name, the text of each part family file of ``--parts`` and
    the built parts (pickled). ``digest`` (SHA-256 of all of it) names it; a Dask worker
    builds one context per digest (:mod:`rgmcad.runs.dask_executor`)."""

    scenario_name: str
    scenario_text: str
    families: tuple[tuple[str, str], ...]
    parts: bytes
    digest: str

    @classmethod
    def of(cls, problem: ScenarioProblem) -> ContextPayload:
        import pickle

        text = Path(problem.scenario_path).read_text(encoding="utf-8")
        families = () if problem.parts_dir is None else tuple(
            (f.name, f.read_text(encoding="utf-8"))
            for f in sorted(Path(problem.parts_dir).glob("*.py")))
        parts = pickle.dumps(dict(problem.parts), protocol=pickle.HIGHEST_PROTOCOL)
        h = hashlib.sha256(text.encode())
        for name, source in families:
            h.update(b"\0" + name.encode() + b"\0" + source.encode())
        h.update(b"\0" + hashlib.sha256(parts).digest())
        return cls(Path(problem.scenario_path).name, text, families, parts, h.hexdigest())

    def context(self) -> ScenarioContext:
        """The context, built here from this payload alone (the part families in a
        temporary folder, gone once loaded)."""
        import pickle
        import tempfile
        import tomllib

        from rgmcad.scene.loader import parse_scenario

        data = tomllib.loads(self.scenario_text)
        if not self.families:
            scenario = parse_scenario(data, where=self.scenario_name,
                                      path=Path(self.scenario_name))
        else:
            with tempfile.TemporaryDirectory(prefix="rgmcad-parts-") as folder:
                for name, source in self.families:
                    (Path(folder) / name).write_text(source, encoding="utf-8")
                scenario = parse_scenario(data, where=self.scenario_name,
                                          path=Path(self.scenario_name), parts_dir=Path(folder))
        return ScenarioContext(scenario, pickle.loads(self.parts))  # noqa: S301 - our client


def simulate_task(context: ScenarioContext, x: np.ndarray) -> SimRecord:
    """``context.simulate_one(x)``: a task for :meth:`~rgmcad.runs.executor.Executor.map_context`."""
    return context.simulate_one(x)


def simulate_layout_task(context: ScenarioContext, item: tuple) -> SimRecord:
    """``context.simulate_one(x, known_valid)`` for ``item = (x, known_valid)``: a layout that
    this run already found valid is not tested again; ``item = (x, known_valid, physics)``
    simulates it with that physical draw, or, for a tuple of draws, in each of them in turn
    (stopping at an invalid layout), labelled by :func:`worst_of`."""
    x, known_valid, *physics = item
    if physics and isinstance(physics[0], tuple):
        records = []
        for world in physics[0]:
            records.append(context.simulate_one(x, known_valid=known_valid, physics=world))
            if not records[-1].valid:
                break
            known_valid = True
        return worst_of(records)
    if physics and physics[0] is not None:
        return context.simulate_one(x, known_valid=known_valid, physics=physics[0])
    return context.simulate_one(x, known_valid=True) if known_valid else context.simulate_one(x)


def simulate_values_task(context: ScenarioContext, values: np.ndarray) -> SimRecord:
    """``context.simulate_values(values)``: a layout given by its real parameter values."""
    return context.simulate_values(values)


def worst_of(records: Sequence[SimRecord]) -> SimRecord:
    """One record for a layout simulated in several worlds: a success only where every world
    succeeded; an event failed where any world failed it (at the earliest such time),
    succeeded where every world did (at the latest), otherwise unresolved; seconds added."""
    if not records[-1].valid:
        return replace(records[-1], seconds=sum(r.seconds for r in records))
    outcome = Outcome.SUCCESS if all(r.outcome is Outcome.SUCCESS for r in records) \
        else Outcome.FAILURE
    events = {}
    for name in records[0].events:
        pairs = [r.events[name] for r in records]
        failed = [t for lab, t in pairs if lab is False]
        if failed:
            events[name] = (False, min((t for t in failed if t is not None), default=None))
        elif all(lab is True for lab, _ in pairs):
            events[name] = (True, max((t for _, t in pairs if t is not None), default=None))
        else:
            events[name] = (None, None)
    return SimRecord(True, outcome, events, sum(r.seconds for r in records))


def validity_task(context: ScenarioContext, X: np.ndarray) -> np.ndarray:
    """``context.validity(X)``: a task for :func:`~rgmcad.runs.executor.map_blocks`."""
    return context.validity(X)


@dataclass(frozen=True, eq=False)
class ScenarioProblem:
    """The :class:`~rgmcad.learning.oracles.Problem` of a scenario file.

    Parameters
    ----------
    scenario_path : str or Path
        The scenario (TOML).
    build_dir : str or Path
        The part cache (parts are built there if missing).
    parts_dir : str or Path, optional
        The folder of part families (``rgmcad --parts DIR``); default: the shipped ones.

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
    parts_dir: str | None = None
    dimension: int = field(init=False)
    event_parents: Mapping[str, tuple[str, ...]] = field(init=False)
    any_joins: frozenset[str] = field(init=False)
    event_dimensions: Mapping[str, tuple[int, ...]] = field(init=False)
    _context: ScenarioContext | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "scenario_path", str(Path(self.scenario_path).resolve()))
        object.__setattr__(self, "build_dir", str(Path(self.build_dir).resolve()))
        if self.parts_dir is not None:
            object.__setattr__(self, "parts_dir", str(Path(self.parts_dir).resolve()))
        scenario = self.scenario
        object.__setattr__(self, "dimension", scenario.dimension)
        object.__setattr__(self, "event_parents", event_parents(scenario))
        object.__setattr__(self, "any_joins", any_joins(scenario))
        object.__setattr__(self, "event_dimensions", event_dimensions(scenario))

    def __getstate__(self):  # the context stays in its process
        return {"scenario_path": self.scenario_path, "build_dir": self.build_dir,
                "parts_dir": self.parts_dir, "dimension": self.dimension,
                "event_parents": dict(self.event_parents), "any_joins": self.any_joins,
                "event_dimensions": dict(self.event_dimensions)}

    def __setstate__(self, state):
        object.__setattr__(self, "_context", None)
        for k, v in state.items():
            object.__setattr__(self, k, v)

    def context(self) -> ScenarioContext:
        """This process's :class:`ScenarioContext` of the problem, loaded on first use (a
        worker pool's initializer: ``make_executor(workers, problem.context)``)."""
        if self._context is None:
            object.__setattr__(self, "_context",
                               ScenarioContext.load(self.scenario_path, self.build_dir,
                                                    self.parts_dir))
        return self._context

    def payload(self) -> ContextPayload:
        """This problem's context as data for machines without its files."""
        return ContextPayload.of(self)

    @property
    def scenario(self):
        """The loaded :class:`~rgmcad.scene.model.Scenario`."""
        return self.context().scenario

    @property
    def parts(self) -> dict:
        """Built parts by object name."""
        return self.context().parts

    def values(self, x) -> np.ndarray:
        """Real parameter values (d,) of a design vector (d,)."""
        return self.context().values(x)

    # --- Problem protocol -----------------------------------------------------------------

    def validity(self, X: np.ndarray) -> np.ndarray:
        """(n,) bool: whether each row of ``X`` (n, d) is physically valid."""
        return self.context().validity(X)

    def penetration(self, x: np.ndarray) -> float:
        """Summed penetration depth (m) beyond the validity tolerance; 0 iff valid."""
        return float(self.context().check(np.asarray(x, dtype=float).reshape(-1)).penetration)

    def simulate(self, X: np.ndarray) -> list:
        """One :class:`Label` per row of ``X`` (n, d), in order."""
        return [r.label() for r in self.simulate_records(X)]

    # --- richer outputs ----------------------------------------------------------------------

    def simulate_records(self, X: np.ndarray | Sequence) -> list[SimRecord]:
        """Simulate each row of ``X`` (n, d); one :class:`SimRecord` per row, in order."""
        return [self.simulate_one(x) for x in np.atleast_2d(np.asarray(X, dtype=float))]

    def simulate_one(self, x: np.ndarray) -> SimRecord:
        """Simulate the design vector ``x`` (d,) (the validity test included)."""
        return self.context().simulate_one(x)
