"""Scenario files: declarative TOML describing a contraption, read into frozen values.

A scenario names its objects (a part family, its parameters, physical properties, a pose
relative to a parent), generated domino runs, joints, the free layout parameters with their
ranges (the design space), the causal graph of expected events, the simulation settings and
named layouts. ``docs`` in the README describe the format; this module checks every key and
raises :class:`~rgmcad.errors.ScenarioError` naming the file, the key and what is allowed.
The values it returns are the types of :mod:`rgmcad.scene.model`.
"""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path

import networkx as nx
import numpy as np

from rgmcad.errors import ScenarioError
from rgmcad.geometry import POSE_KEYS
from rgmcad.parts.family import load_families
from rgmcad.scene import dominoes
from rgmcad.scene.loader_checks import check_keys, check_name, expect
from rgmcad.scene.loader_events import parse_events
from rgmcad.scene.model import (
    FRAME,
    PHYSICAL_KEYS,
    SIMULATION_KEYS,
    FreeParameter,
    Joint,
    Physical,
    Scenario,
    SceneObject,
    SimulationSettings,
)

TOP_KEYS = ("name", "description", "parts", "simulation", "objects", "runs", "joints",
            "events", "layouts")
OBJECT_KEYS = ("part", "params", "parent", "pose", "free", "note", *PHYSICAL_KEYS)
RUN_KEYS = ("domino", "path", "tilt", "parent", "pose", "free", "note", *PHYSICAL_KEYS)


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
        parts_dir = (path.parent / expect(data["parts"], str, path, "parts")).resolve()
    return parse_scenario(data, where=str(path), path=path, parts_dir=parts_dir)


def parse_scenario(data: Mapping, *, where: str = "<scenario>", path: Path | None = None,
                   parts_dir: Path | None = None) -> Scenario:
    """Check a scenario's TOML data (a mapping) and read it; ``where`` names it in errors.

    The part families come from ``parts_dir`` (default: the shipped ones); the scenario keeps
    that registry (``Scenario.families``).
    """
    check_keys(data, TOP_KEYS, where, "")
    families = load_families(parts_dir)
    name = expect(data.get("name", path.stem if path else "scenario"), str, where, "name")
    settings = _parse_settings(data.get("simulation", {}), where)

    objects: dict[str, SceneObject] = {}
    free: list[FreeParameter] = []
    runs: dict[str, tuple[str, ...]] = {}

    raw_objects = expect(data.get("objects", {}), dict, where, "objects")
    raw_runs = expect(data.get("runs", {}), dict, where, "runs")
    for obj_name, raw in raw_objects.items():
        key = f"objects.{obj_name}"
        check_name(obj_name, where, key)
        raw = expect(raw, dict, where, key)
        check_keys(raw, OBJECT_KEYS, where, key)
        part = expect(raw.get("part", None), str, where, f"{key}.part")
        if part == FRAME:
            params = None
            if "params" in raw:
                raise ScenarioError(where, f"{key}.params", "a frame has no parameters")
        else:
            if part not in families:
                allowed = ", ".join(sorted([*families, FRAME]))
                raise ScenarioError(where, f"{key}.part", f"unknown part {part!r}; allowed: {allowed}")
            params = families[part].make_params(
                expect(raw.get("params", {}), dict, where, f"{key}.params"),
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
        check_name(run_name, where, key)
        if run_name in objects:
            raise ScenarioError(where, key, "a run cannot share its name with an object")
        raw = expect(raw, dict, where, key)
        check_keys(raw, RUN_KEYS, where, key)
        pose = _parse_pose(raw.get("pose", {}), where, f"{key}.pose")
        objects[run_name] = SceneObject(run_name, FRAME, None, Physical(), raw.get("parent"), pose)
        free.extend(_parse_free(raw.get("free", {}), run_name, where, f"{key}.free"))
        names = _expand_run(run_name, raw, families, objects, where, key)
        runs[run_name] = tuple(names)

    _check_parents(objects, where)
    joints = _parse_joints(data.get("joints", []), objects, families, where)
    events = parse_events(data.get("events", {}), objects, families, runs, where, settings)
    layouts = _parse_layouts(data.get("layouts", {}), objects, free, where)

    scenario = Scenario(
        name=name, path=path,
        description=expect(data.get("description", ""), str, where, "description"),
        objects=objects, free=tuple(free), joints=joints, events=events, settings=settings,
        layouts=layouts, families=families, runs=runs,
    )
    if not events:
        raise ScenarioError(where, "events", "a scenario needs a causal graph of at least one event")
    return scenario


def _expand_run(run_name, raw, families, objects, where, key) -> list[str]:
    domino = expect(raw.get("domino"), dict, where, f"{key}.domino")
    if not set(domino) <= {"thickness", "width", "height"}:
        raise ScenarioError(where, f"{key}.domino", "allowed keys: thickness, width, height")
    params = families["box"].make_params(
        {"length": domino.get("thickness"), "width": domino.get("width"),
         "height": domino.get("height")}, where=where, key=f"{key}.domino")
    path = dict(expect(raw.get("path"), dict, where, f"{key}.path"))
    kind = path.pop("kind", None)
    if kind not in dominoes.PATHS:
        raise ScenarioError(where, f"{key}.path.kind",
                            f"unknown path {kind!r}; allowed: {', '.join(dominoes.PATHS)}")
    try:
        coords = dominoes.PATHS[kind](**path)
    except (TypeError, ValueError) as exc:
        raise ScenarioError(where, f"{key}.path", f"bad {kind} path: {exc}") from None
    tilt = float(expect(raw.get("tilt", 0.0), (int, float), where, f"{key}.tilt"))
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
    raw = expect(raw, dict, where, "simulation")
    check_keys(raw, SIMULATION_KEYS, where, "simulation")
    defaults = SimulationSettings()
    values = {}
    for k, v in raw.items():
        kind = type(getattr(defaults, k))
        if kind is bool:
            values[k] = expect(v, bool, where, f"simulation.{k}")
        elif kind is int:
            values[k] = expect(v, int, where, f"simulation.{k}")
        else:
            values[k] = float(expect(v, (int, float), where, f"simulation.{k}"))
        if kind is not bool and values[k] <= 0 and k not in ("restitution_velocity_threshold",):
            raise ScenarioError(where, f"simulation.{k}", "must be > 0")
    return SimulationSettings(**values)


def _parse_physical(raw, where, key) -> Physical:
    values = {}
    for k in PHYSICAL_KEYS:
        if k in raw:
            v = float(expect(raw[k], (int, float), where, f"{key}.{k}"))
            if v < 0 or (k in ("mass", "density") and v <= 0):
                raise ScenarioError(where, f"{key}.{k}", "must be positive")
            values[k] = v
    if "mass" in values and "density" in values:
        raise ScenarioError(where, key, "give mass or density, not both")
    return Physical(**values)


def _parse_pose(raw, where, key) -> tuple[float, ...]:
    raw = expect(raw, dict, where, key)
    check_keys(raw, POSE_KEYS, where, key)
    return tuple(float(expect(raw.get(k, 0.0), (int, float), where, f"{key}.{k}"))
                 for k in POSE_KEYS)


def _parse_free(raw, obj_name, where, key) -> list[FreeParameter]:
    raw = expect(raw, dict, where, key)
    check_keys(raw, POSE_KEYS, where, key)
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
    raw = expect(raw, list, where, "joints")
    joints = []
    for i, j in enumerate(raw):
        key = f"joints[{i}]"
        j = expect(j, dict, where, key)
        kind = j.get("kind")
        if kind == "weld":
            check_keys(j, ("kind", "objects"), where, key)
        elif kind == "hinge":
            check_keys(j, ("kind", "objects", "point", "axis"), where, key)
        else:
            raise ScenarioError(where, f"{key}.kind", f"unknown joint {kind!r}; allowed: weld, hinge")
        names = expect(j.get("objects"), list, where, f"{key}.objects")
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
                v = expect(j[k], list, where, f"{key}.{k}")
                if len(v) != 3:
                    raise ScenarioError(where, f"{key}.{k}", "expected 3 numbers")
                vec[k] = tuple(float(x) for x in v)
        if "axis" in vec and np.linalg.norm(vec["axis"]) == 0:
            raise ScenarioError(where, f"{key}.axis", "the axis cannot be zero")
        joints.append(Joint(kind, tuple(names), **vec))
    return tuple(joints)


def _parse_layouts(raw, objects, free, where) -> dict[str, dict[str, float]]:
    raw = expect(raw, dict, where, "layouts")
    by_name = {f.name: f for f in free}
    layouts = {"initial": {f.name: objects[f.object].pose[POSE_KEYS.index(f.component)]
                           for f in free}}
    for layout_name, table in raw.items():
        key = f"layouts.{layout_name}"
        table = expect(table, dict, where, key)
        values = dict(layouts["initial"])
        for obj_name, comps in table.items():
            comps = expect(comps, dict, where, f"{key}.{obj_name}")
            for comp, value in comps.items():
                pname = f"{obj_name}.{comp}"
                if pname not in by_name:
                    raise ScenarioError(where, f"{key}.{pname}", "not a free parameter; allowed: "
                                        + ", ".join(by_name))
                values[pname] = float(expect(value, (int, float), where, f"{key}.{pname}"))
        layouts[layout_name] = values
    return layouts
