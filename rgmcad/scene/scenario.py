"""Scenario files: declarative TOML describing a contraption, read into frozen values.

A scenario names its objects (a part family, its parameters, physical properties, a pose
relative to a parent), generated domino runs, joints, the free layout parameters with their
ranges (the design space), the causal graph of expected events, the simulation settings and
named layouts. ``docs`` in the README describe the format; this module checks every key and
raises :class:`~rgmcad.errors.ScenarioError` naming the file, the key and what is allowed.
"""

from __future__ import annotations

import dataclasses
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np

from rgmcad.errors import ScenarioError
from rgmcad.geometry import ANGLE_KEYS, POSE_KEYS
from rgmcad.parts.family import MAIN, Family, load_families
from rgmcad.scene import dominoes
from rgmcad.scene.eventspec import ENDS, EVENT_TYPES, NEGATE_VALUES, POINT_KEYS, Negation

FRAME = "frame"
"""Part name of a pure reference frame: it has no body and carries poses for its children."""


@dataclass(frozen=True)
class Physical:
    """Physical properties of an object's main body (SI units).

    Neither ``mass`` nor ``density``: the body is static. Friction and restitution combine by
    product between two bodies (Bullet's rule). Damping is zero unless asked for.
    """

    mass: float | None = None  # kg
    density: float | None = None  # kg/m^3
    friction: float = 0.5
    restitution: float = 0.0
    linear_damping: float = 0.0
    angular_damping: float = 0.0
    rolling_friction: float = 0.0
    spinning_friction: float = 0.0

    @property
    def static(self) -> bool:
        return self.mass is None and self.density is None


PHYSICAL_KEYS = tuple(f.name for f in dataclasses.fields(Physical))


@dataclass(frozen=True)
class SceneObject:
    """One object: a part instance (or a frame) posed relative to its parent.

    ``pose`` is ``(x, y, z, heading, pitch, roll)`` in metres and degrees, relative to the
    parent's frame (the world when ``parent`` is None).
    """

    name: str
    part: str  # family name, or FRAME
    params: Any  # the family's Params instance; None for frames
    physical: Physical
    parent: str | None
    pose: tuple[float, ...]
    run: str | None = None  # the domino run it belongs to


@dataclass(frozen=True)
class FreeParameter:
    """A pose component left free for the layout, with its range in real units."""

    object: str
    component: str  # one of POSE_KEYS
    low: float
    high: float

    @property
    def name(self) -> str:
        return f"{self.object}.{self.component}"

    @property
    def unit(self) -> str:
        return "deg" if self.component in ANGLE_KEYS else "m"


@dataclass(frozen=True)
class Joint:
    """A joint declared in the scenario (parts bring their own, e.g. a lever's hinge).

    ``weld``: ``objects`` move as one rigid body. ``hinge``: ``objects[0]`` turns about the axis
    ``axis`` through ``point`` (both in its own frame), relative to ``objects[1]`` or the world.
    """

    kind: str  # "weld" | "hinge"
    objects: tuple[str, ...]
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)


@dataclass(frozen=True)
class EventSpec:
    """One node of the causal graph.

    ``negate`` is a :class:`~rgmcad.scene.eventspec.Negation` (a bool is read as OFF / ONCE).
    ``point`` or ``end`` (events whose type ``takes_point``; at most one) name the point of the
    body whose motion counts: coordinates in the body's part frame, or the centre of one face
    of its bounding box (one of :data:`~rgmcad.scene.eventspec.ENDS`). Neither: the centre of mass.
    """

    name: str
    type: str
    objects: dict[str, str]  # role -> object name
    params: dict[str, float]
    after: tuple[str, ...] = ()
    join: str = "all"  # "all" | "any"
    negate: Negation = Negation.OFF
    hold: float = 0.0  # s the condition must hold before success
    timeout: float | None = None  # s after waking; None = the scenario's event_timeout
    description: str = ""
    point: tuple[float, float, float] | None = None  # m, in the body's part frame
    end: str | None = None  # "+x" | "-x" | "+y" | "-y" | "+z" | "-z"

    def __post_init__(self):
        if not isinstance(self.negate, Negation):
            object.__setattr__(self, "negate", Negation(bool(self.negate)))


@dataclass(frozen=True)
class SimulationSettings:
    """Every setting that changes a trajectory, pinned (pybullet's defaults drift by version).

    Defaults follow the paper's engine where it matters (time step 1/500 s, 2 s event timeout,
    10 solver iterations, no split impulse); ``ccd`` enables continuous collision detection for
    small fast bodies, which the paper's engine lacked.
    """

    timestep: float = 0.002
    duration: float = 4.0
    event_timeout: float = 2.0
    gravity: float = 9.81
    solver_iterations: int = 10
    erp: float = 0.2
    contact_erp: float = 0.2
    friction_erp: float = 0.2
    split_impulse: bool = False
    contact_breaking_threshold: float = 0.002
    restitution_velocity_threshold: float = 0.05
    convex_margin: float = 1e-4
    ccd: bool = True


SIMULATION_KEYS = tuple(f.name for f in dataclasses.fields(SimulationSettings))


@dataclass(frozen=True)
class Scenario:
    name: str
    path: Path | None
    description: str
    objects: dict[str, SceneObject]  # file order; domino runs expanded
    free: tuple[FreeParameter, ...]  # design-vector order
    joints: tuple[Joint, ...]
    events: dict[str, EventSpec]  # file order
    settings: SimulationSettings
    layouts: dict[str, dict[str, float]]  # name -> {free parameter name: real value}
    families: dict[str, Family] = field(repr=False, default_factory=dict)
    runs: dict[str, tuple[str, ...]] = field(default_factory=dict)  # run -> domino names

    @property
    def dimension(self) -> int:
        return len(self.free)

    @property
    def root_event(self) -> str:
        return next(n for n, e in self.events.items() if not e.after)

    def causal_graph(self) -> nx.DiGraph:
        graph = nx.DiGraph()
        graph.add_nodes_from(self.events)
        for name, event in self.events.items():
            graph.add_edges_from((parent, name) for parent in event.after)
        return graph

    def family(self, obj: SceneObject) -> Family:
        return self.families[obj.part]

    def body_objects(self) -> list[SceneObject]:
        """Objects that are parts (frames excluded), in file order."""
        return [o for o in self.objects.values() if o.part != FRAME]

    def body_names(self) -> list[str]:
        """Every body a scene has: main bodies by object name, extra bodies as ``obj.key``."""
        names = []
        for obj in self.body_objects():
            family = self.family(obj)
            names.append(obj.name)
            names.extend(f"{obj.name}.{k}" for k in family.fixed_bodies(obj.params))
        return names


# --- reading ----------------------------------------------------------------------------------

TOP_KEYS = ("name", "description", "parts", "simulation", "objects", "runs", "joints",
            "events", "layouts")
OBJECT_KEYS = ("part", "params", "parent", "pose", "free", "note", *PHYSICAL_KEYS)
RUN_KEYS = ("domino", "path", "tilt", "parent", "pose", "free", "note", *PHYSICAL_KEYS)
EVENT_COMMON_KEYS = ("type", "after", "join", "negate", "hold", "timeout", "description")
EVENT_POINT_KEYS = ("point", "end")  # events whose type takes_point


def load_scenario(path: str | Path, *, parts_dir: Path | None = None) -> Scenario:
    """Read and check a scenario file. Raises ScenarioError on any bad input."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ScenarioError(str(path), "", f"cannot read the file ({exc.strerror})") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(str(path), "", f"not valid TOML: {exc}") from None
    if parts_dir is None and "parts" in data:
        parts_dir = (path.parent / _expect(data["parts"], str, path, "parts")).resolve()
    return parse_scenario(data, where=str(path), path=path, parts_dir=parts_dir)


def parse_scenario(data: Mapping, *, where: str = "<scenario>", path: Path | None = None,
                   parts_dir: Path | None = None) -> Scenario:
    _check_keys(data, TOP_KEYS, where, "")
    families = load_families(parts_dir)
    name = _expect(data.get("name", path.stem if path else "scenario"), str, where, "name")
    settings = _parse_settings(data.get("simulation", {}), where)

    objects: dict[str, SceneObject] = {}
    free: list[FreeParameter] = []
    runs: dict[str, tuple[str, ...]] = {}

    raw_objects = _expect(data.get("objects", {}), dict, where, "objects")
    raw_runs = _expect(data.get("runs", {}), dict, where, "runs")
    for obj_name, raw in raw_objects.items():
        key = f"objects.{obj_name}"
        _check_name(obj_name, where, key)
        raw = _expect(raw, dict, where, key)
        _check_keys(raw, OBJECT_KEYS, where, key)
        part = _expect(raw.get("part", None), str, where, f"{key}.part")
        if part == FRAME:
            params = None
            if "params" in raw:
                raise ScenarioError(where, f"{key}.params", "a frame has no parameters")
        else:
            if part not in families:
                allowed = ", ".join(sorted([*families, FRAME]))
                raise ScenarioError(where, f"{key}.part", f"unknown part {part!r}; allowed: {allowed}")
            params = families[part].make_params(
                _expect(raw.get("params", {}), dict, where, f"{key}.params"),
                where=where, key=f"{key}.params")
        physical = _parse_physical(raw, where, key)
        if part == FRAME and not physical.static:
            raise ScenarioError(where, key, "a frame has no body: remove mass/density")
        if part != FRAME and families[part].infinite and not physical.static:
            raise ScenarioError(where, key, "an infinite plane is always static")
        pose = _parse_pose(raw.get("pose", {}), where, f"{key}.pose")
        objects[obj_name] = SceneObject(obj_name, part, params, physical,
                                        raw.get("parent"), pose)
        free.extend(_parse_free(raw.get("free", {}), obj_name, where, f"{key}.free"))

    for run_name, raw in raw_runs.items():
        key = f"runs.{run_name}"
        _check_name(run_name, where, key)
        if run_name in objects:
            raise ScenarioError(where, key, "a run cannot share its name with an object")
        raw = _expect(raw, dict, where, key)
        _check_keys(raw, RUN_KEYS, where, key)
        pose = _parse_pose(raw.get("pose", {}), where, f"{key}.pose")
        objects[run_name] = SceneObject(run_name, FRAME, None, Physical(), raw.get("parent"), pose)
        free.extend(_parse_free(raw.get("free", {}), run_name, where, f"{key}.free"))
        names = _expand_run(run_name, raw, families, objects, where, key)
        runs[run_name] = tuple(names)

    _check_parents(objects, where)
    joints = _parse_joints(data.get("joints", []), objects, families, where)
    events = _parse_events(data.get("events", {}), objects, families, runs, where,
                           settings)
    layouts = _parse_layouts(data.get("layouts", {}), objects, free, where)

    scenario = Scenario(
        name=name, path=path,
        description=_expect(data.get("description", ""), str, where, "description"),
        objects=objects, free=tuple(free), joints=joints, events=events, settings=settings,
        layouts=layouts, families=families, runs=runs,
    )
    if not events:
        raise ScenarioError(where, "events", "a scenario needs a causal graph of at least one event")
    return scenario


def _expand_run(run_name, raw, families, objects, where, key) -> list[str]:
    domino = _expect(raw.get("domino"), dict, where, f"{key}.domino")
    params = families["box"].make_params(
        {"length": domino.get("thickness"), "width": domino.get("width"),
         "height": domino.get("height")} if set(domino) <= {"thickness", "width", "height"}
        else _raise(ScenarioError(where, f"{key}.domino",
                                  "allowed keys: thickness, width, height")),
        where=where, key=f"{key}.domino")
    path = dict(_expect(raw.get("path"), dict, where, f"{key}.path"))
    kind = path.pop("kind", None)
    if kind not in dominoes.PATHS:
        raise ScenarioError(where, f"{key}.path.kind",
                            f"unknown path {kind!r}; allowed: {', '.join(dominoes.PATHS)}")
    try:
        coords = dominoes.PATHS[kind](**path)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(where, f"{key}.path", f"bad {kind} path: {exc}") from None
    tilt = float(_expect(raw.get("tilt", 0.0), (int, float), where, f"{key}.tilt"))
    physical = _parse_physical(raw, where, key)
    names = []
    t, h = params.length, params.height
    for i, (x, y, heading) in enumerate(coords):
        name = f"{run_name}[{i}]"
        if name in objects:
            raise ScenarioError(where, key, f"object {name!r} already exists")
        pose = (float(x), float(y), h / 2, float(heading), 0.0, 0.0)
        if i == 0 and tilt:
            pose = _tilted(pose, t, h, tilt)
        objects[name] = SceneObject(name, "box", params, physical, run_name, pose, run=run_name)
        names.append(name)
    return names


def _tilted(pose, thickness, height, tilt_deg):
    """Pose of a domino leaned forward by ``tilt_deg`` about its bottom front edge.

    The paper's code turned the domino about a point one full thickness ahead and one full
    height below its centre, which lifts it off the ground; we turn it about the real edge.
    """
    from rgmcad.geometry import pose6_of, pose_matrix, translation

    standing = pose_matrix(pose)
    edge = np.array([thickness / 2, 0.0, -height / 2])
    lean = translation(edge) @ pose_matrix((0, 0, 0, 0, 0, tilt_deg)) @ translation(-edge)
    return tuple(float(v) for v in pose6_of(standing @ lean))


def _parse_settings(raw, where) -> SimulationSettings:
    raw = _expect(raw, dict, where, "simulation")
    _check_keys(raw, SIMULATION_KEYS, where, "simulation")
    defaults = SimulationSettings()
    values = {}
    for k, v in raw.items():
        kind = type(getattr(defaults, k))
        if kind is bool:
            values[k] = _expect(v, bool, where, f"simulation.{k}")
        elif kind is int:
            values[k] = _expect(v, int, where, f"simulation.{k}")
        else:
            values[k] = float(_expect(v, (int, float), where, f"simulation.{k}"))
        if kind is not bool and values[k] <= 0 and k not in ("restitution_velocity_threshold",):
            raise ScenarioError(where, f"simulation.{k}", "must be > 0")
    return SimulationSettings(**values)


def _parse_physical(raw, where, key) -> Physical:
    values = {}
    for k in PHYSICAL_KEYS:
        if k in raw:
            v = float(_expect(raw[k], (int, float), where, f"{key}.{k}"))
            if v < 0 or (k in ("mass", "density") and v <= 0):
                raise ScenarioError(where, f"{key}.{k}", "must be positive")
            values[k] = v
    if "mass" in values and "density" in values:
        raise ScenarioError(where, key, "give mass or density, not both")
    return Physical(**values)


def _parse_pose(raw, where, key) -> tuple[float, ...]:
    raw = _expect(raw, dict, where, key)
    _check_keys(raw, POSE_KEYS, where, key)
    return tuple(float(_expect(raw.get(k, 0.0), (int, float), where, f"{key}.{k}"))
                 for k in POSE_KEYS)


def _parse_free(raw, obj_name, where, key) -> list[FreeParameter]:
    raw = _expect(raw, dict, where, key)
    _check_keys(raw, POSE_KEYS, where, key)
    out = []
    for component in POSE_KEYS:  # canonical order, whatever the file's order
        if component not in raw:
            continue
        rng = raw[component]
        if (not isinstance(rng, list) or len(rng) != 2
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in rng)):
            raise ScenarioError(where, f"{key}.{component}", "expected a range [min, max]")
        low, high = float(rng[0]), float(rng[1])
        if not low < high:
            raise ScenarioError(where, f"{key}.{component}",
                                f"range min must be < max, got [{low}, {high}]")
        out.append(FreeParameter(obj_name, component, low, high))
    return out


def _check_parents(objects, where):
    graph = nx.DiGraph()
    for name, obj in objects.items():
        graph.add_node(name)
        if obj.parent is not None:
            if not isinstance(obj.parent, str) or obj.parent not in objects:
                key = f"objects.{name}.parent" if obj.run is None else f"runs.{obj.parent}"
                raise ScenarioError(where, key, f"unknown parent {obj.parent!r}; "
                                    "allowed: any object or run name")
            graph.add_edge(obj.parent, name)
    if not nx.is_directed_acyclic_graph(graph):
        cycle = " -> ".join(e[0] for e in nx.find_cycle(graph))
        raise ScenarioError(where, "objects", f"the parents form a cycle: {cycle}")


def _parse_joints(raw, objects, families, where) -> tuple[Joint, ...]:
    raw = _expect(raw, list, where, "joints")
    joints = []
    for i, j in enumerate(raw):
        key = f"joints[{i}]"
        j = _expect(j, dict, where, key)
        kind = j.get("kind")
        if kind == "weld":
            _check_keys(j, ("kind", "objects"), where, key)
        elif kind == "hinge":
            _check_keys(j, ("kind", "objects", "point", "axis"), where, key)
        else:
            raise ScenarioError(where, f"{key}.kind", f"unknown joint {kind!r}; allowed: weld, hinge")
        names = _expect(j.get("objects"), list, where, f"{key}.objects")
        wanted = 2 if kind == "weld" else (1, 2)
        if len(names) not in (wanted if isinstance(wanted, tuple) else (wanted,)):
            raise ScenarioError(where, f"{key}.objects",
                                "a weld joins two objects; a hinge names one (hinged to the "
                                "world) or two (the moving one first)")
        for n in names:
            if n not in objects or objects[n].part == FRAME:
                raise ScenarioError(where, f"{key}.objects", f"unknown body {n!r}")
        vec = {}
        for k in ("point", "axis"):
            if k in j:
                v = _expect(j[k], list, where, f"{key}.{k}")
                if len(v) != 3:
                    raise ScenarioError(where, f"{key}.{k}", "expected 3 numbers")
                vec[k] = tuple(float(x) for x in v)
        if "axis" in vec and np.linalg.norm(vec["axis"]) == 0:
            raise ScenarioError(where, f"{key}.axis", "the axis cannot be zero")
        joints.append(Joint(kind, tuple(names), **vec))
    return tuple(joints)


def _resolve_body(ref, objects, families, runs, where, key) -> str:
    """Canonical body name for an event argument; accepts ``run[-1]`` for a run's last domino."""
    if not isinstance(ref, str):
        raise ScenarioError(where, key, f"expected an object name, got {ref!r}")
    if "[" in ref and ref.endswith("]"):
        run, _, index = ref[:-1].partition("[")
        if run in runs:
            try:
                i = int(index)
                return runs[run][i]
            except (ValueError, IndexError):
                raise ScenarioError(where, key, f"run {run!r} has {len(runs[run])} dominoes; "
                                    f"{ref!r} is not one of them") from None
    obj_name, _, sub = ref.partition(".")
    obj = objects.get(obj_name)
    if obj is not None and obj.part != FRAME:
        if not sub:
            return ref
        if sub in families[obj.part].fixed_bodies(obj.params):
            return ref
    raise ScenarioError(where, key, f"unknown object {ref!r}; events name bodies "
                        "(objects that are parts, run[i] dominoes, or object.axle)")


def _parse_events(raw, objects, families, runs, where,
                  settings: SimulationSettings | None = None) -> dict[str, EventSpec]:
    raw = _expect(raw, dict, where, "events")
    settings = settings or SimulationSettings()
    events = {}
    for name, ev in raw.items():
        key = f"events.{name}"
        _check_name(name, where, key)
        ev = _expect(ev, dict, where, key)
        etype = ev.get("type")
        if etype not in EVENT_TYPES:
            raise ScenarioError(where, f"{key}.type", f"unknown event type {etype!r}; "
                                f"allowed: {', '.join(EVENT_TYPES)}")
        spec = EVENT_TYPES[etype]
        extra = EVENT_POINT_KEYS if spec.takes_point else ()
        for k in EVENT_POINT_KEYS:
            if k in ev and not spec.takes_point:
                takers = ", ".join(t.name for t in EVENT_TYPES.values() if t.takes_point)
                raise ScenarioError(where, f"{key}.{k}", f"a {etype} event takes no point or "
                                    f"end (only {takers} do)")
        _check_keys(ev, (*EVENT_COMMON_KEYS, *spec.roles, *spec.params, *extra), where, key)
        roles = {}
        for role in spec.roles:
            if role not in ev:
                raise ScenarioError(where, f"{key}.{role}", f"a {etype} event needs {role!r}")
            roles[role] = _resolve_body(ev[role], objects, families, runs, where, f"{key}.{role}")
        params = {}
        for p, default in spec.params.items():
            if p in ev:
                params[p] = float(_expect(ev[p], (int, float), where, f"{key}.{p}"))
            elif default is None:
                raise ScenarioError(where, f"{key}.{p}", f"a {etype} event needs {p!r}")
            else:
                params[p] = default
        after = _expect(ev.get("after", []), list, where, f"{key}.after")
        join = ev.get("join", "all")
        if join not in ("all", "any"):
            raise ScenarioError(where, f"{key}.join", f"unknown join {join!r}; allowed: all, any")
        negate = _parse_negate(ev.get("negate", False), where, f"{key}.negate")
        timeout = ev.get("timeout")
        if timeout is not None:
            timeout = float(_expect(timeout, (int, float), where, f"{key}.timeout"))
            if timeout <= 0:
                raise ScenarioError(where, f"{key}.timeout", f"must be > 0, got {timeout:g}")
        hold = _parse_hold(ev.get("hold", 0.0), timeout, settings, where, key)
        if negate is Negation.ALWAYS:
            _check_always_fits(timeout, settings, where, key)
        point, end = _parse_point(ev, roles, objects, families, where, key)
        events[name] = EventSpec(
            name=name, type=etype, objects=roles, params=params, after=tuple(after), join=join,
            negate=negate, hold=hold, timeout=timeout,
            description=_expect(ev.get("description", ""), str, where, f"{key}.description"),
            point=point, end=end,
        )
    for name, ev in events.items():
        for parent in ev.after:
            if parent not in events:
                raise ScenarioError(where, f"events.{name}.after",
                                    f"unknown event {parent!r}; allowed: {', '.join(events)}")
            if parent == name:
                raise ScenarioError(where, f"events.{name}.after", "an event cannot follow itself")
    if events:
        graph = nx.DiGraph()
        graph.add_nodes_from(events)
        graph.add_edges_from((p, n) for n, e in events.items() for p in e.after)
        if not nx.is_directed_acyclic_graph(graph):
            cycle = " -> ".join(e[0] for e in nx.find_cycle(graph))
            raise ScenarioError(where, "events", f"the causal graph has a cycle: {cycle}")
        roots = [n for n, e in events.items() if not e.after]
        if len(roots) != 1:
            raise ScenarioError(where, "events", "the causal graph needs exactly one root event "
                                f"(one without `after`); found {len(roots)}: {', '.join(roots)}")
    return events


def _parse_negate(value, where, key) -> Negation:
    if isinstance(value, bool):
        return Negation(value)
    if value == Negation.ALWAYS.value:
        return Negation.ALWAYS
    raise ScenarioError(where, key, f"expected {NEGATE_VALUES}, got {value!r}")


def _parse_hold(value, timeout, settings, where, key) -> float:
    """``hold`` (s): at least 0 and shorter than the event's timeout, or it can never succeed."""
    hold = float(_expect(value, (int, float), where, f"{key}.hold"))
    limit = timeout if timeout is not None else settings.event_timeout
    if not 0 <= hold < limit:
        source = ("its `timeout`" if timeout is not None
                  else "the scenario's [simulation] event_timeout")
        raise ScenarioError(where, f"{key}.hold", f"got {hold:g} s; allowed: 0 <= hold < "
                            f"{limit:g} s, the event's timeout ({source}): a longer hold "
                            "cannot be met before the event times out")
    return hold


def _check_always_fits(timeout, settings, where, key) -> None:
    """A ``negate = "always"`` event succeeds only at its timeout, so that must fit the run."""
    limit = timeout if timeout is not None else settings.event_timeout
    if limit >= settings.duration:
        name = "timeout" if timeout is not None else "negate"
        raise ScenarioError(where, f"{key}.{name}", f"a negate = \"always\" event succeeds at its "
                            f"timeout ({limit:g} s after it wakes), which must be shorter than "
                            f"the simulation's duration ({settings.duration:g} s)")


def _parse_point(ev, roles, objects, families, where, key):
    """(point, end) of an event: at most one given; ``point`` fills missing x, y, z with 0."""
    if "point" in ev and "end" in ev:
        raise ScenarioError(where, f"{key}.point", "give point or end, not both")
    if "end" in ev:
        end = ev["end"]
        if end not in ENDS:
            raise ScenarioError(where, f"{key}.end", f"unknown end {end!r}; allowed: "
                                + ", ".join(f'"{e}"' for e in ENDS))
        for body in roles.values():
            obj_name, sub = body_key(body)
            obj = objects[obj_name]
            if sub == MAIN and families[obj.part].infinite:
                raise ScenarioError(where, f"{key}.end", f"{body!r} is an infinite plane: it "
                                    "has no ends; use point = { x = ..., y = ..., z = ... }")
        return None, end
    if "point" in ev:
        raw = ev["point"]
        what = "a table { x = ..., y = ..., z = ... } (metres, in the body's part frame)"
        if not isinstance(raw, dict):
            raise ScenarioError(where, f"{key}.point", f"expected {what}, got {raw!r}")
        for k, v in raw.items():
            if k not in POINT_KEYS:
                raise ScenarioError(where, f"{key}.point.{k}",
                                    f"unknown key; allowed: {', '.join(POINT_KEYS)}")
            if isinstance(v, bool) or not isinstance(v, int | float) or not np.isfinite(v):
                raise ScenarioError(where, f"{key}.point.{k}",
                                    f"expected a number (metres), got {v!r}")
        return tuple(float(raw.get(k, 0.0)) for k in POINT_KEYS), None
    return None, None


def _parse_layouts(raw, objects, free, where) -> dict[str, dict[str, float]]:
    raw = _expect(raw, dict, where, "layouts")
    by_name = {f.name: f for f in free}
    layouts = {"initial": {f.name: objects[f.object].pose[POSE_KEYS.index(f.component)]
                           for f in free}}
    for layout_name, table in raw.items():
        key = f"layouts.{layout_name}"
        table = _expect(table, dict, where, key)
        values = dict(layouts["initial"])
        for obj_name, comps in table.items():
            comps = _expect(comps, dict, where, f"{key}.{obj_name}")
            for comp, value in comps.items():
                pname = f"{obj_name}.{comp}"
                if pname not in by_name:
                    raise ScenarioError(where, f"{key}.{pname}", "not a free parameter; allowed: "
                                        + ", ".join(by_name))
                values[pname] = float(_expect(value, (int, float), where, f"{key}.{pname}"))
        layouts[layout_name] = values
    return layouts


# --- small checks -----------------------------------------------------------------------------


def _expect(value, kind, where, key):
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if value is None or isinstance(value, bool) and bool not in kinds or not isinstance(value, kinds):
        names = " or ".join({"str": "a string", "dict": "a table", "list": "a list",
                             "int": "an integer", "float": "a number", "bool": "true/false"}
                            [k.__name__] for k in kinds)
        raise ScenarioError(where, key, f"expected {names}, got {value!r}")
    return value


def _check_keys(table, allowed, where, key):
    for k in table:
        if k not in allowed:
            prefix = f"{key}.{k}" if key else k
            raise ScenarioError(where, prefix, f"unknown key; allowed: {', '.join(allowed)}")


def _check_name(name, where, key):
    if not name or any(c in name for c in ".[] "):
        raise ScenarioError(where, key, "names cannot contain '.', '[', ']' or spaces")


def _raise(exc):
    raise exc


def body_key(body: str) -> tuple[str, str]:
    """Split a body name into (object name, part body key)."""
    obj, _, sub = body.partition(".")
    return obj, sub or MAIN
