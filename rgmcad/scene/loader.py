"""Scenario files: declarative TOML describing a contraption, read into frozen values.

A scenario names its objects (a part family, its parameters, physical properties, a pose
relative to a parent), generated domino runs, joints, the free layout parameters with their
ranges (the design space), the causal graph of expected events, the simulation settings and
named layouts. docs/how-to/scenario.md and the generated reference page (rgmcad.reference)
describe the format; this module checks every key and raises
:class:`~rgmcad.errors.ScenarioError` naming the file, the key and what is allowed.
The values it returns are the types of :mod:`rgmcad.scene.model`.
"""

from __future__ import annotations

import dataclasses
import inspect
import math
import tomllib
from collections.abc import Mapping
from pathlib import Path

import networkx as nx
import numpy as np

from rgmcad.errors import ScenarioError
from rgmcad.geometry import POSE_KEYS
from rgmcad.parts.family import load_families
from rgmcad.scene import dominoes, svg_runs
from rgmcad.scene.loader_checks import (
    check_keys,
    check_name,
    check_overlaps,
    check_scenario_name,
    expect,
    key_text,
    one_line,
    read_text,
    reads_as_radians,
    toml_error,
)
from rgmcad.scene.loader_events import parse_events
from rgmcad.scene.loader_ropes import parse_ropes
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
from rgmcad.scene.schema import (
    DOMINO,
    JOINT,
    MAX_BODIES,
    MAX_DEPTH,
    MAX_FREE,
    MAX_JOINTS,
    MAX_LAYOUTS,
    MAX_RUN,
    MAX_STEPS,
    MIN_RANGE,
    MM_AS_M,
    PATHS,
    PHYSICAL,
    POSE,
    RUN,
    SIMULATION,
    SIZE,
    show,
    warn,
    warnings_after_loading,
)

TOP_KEYS = ("name", "description", "simulation", "objects", "runs", "joints", "ropes", "events",
            "layouts")
OBJECT_KEYS = ("part", "params", "parent", "pose", "free", "note", *PHYSICAL_KEYS)
PATH_MAKERS = {**dominoes.PATHS, "svg": svg_runs.svg}
COUNTERS = {"polyline": dominoes.polyline_count, "svg": svg_runs.svg_count}
RUN_KEYS = ("domino", "path", "tilt", "parent", "pose", "free", "note", *PHYSICAL_KEYS)
NO_PARTS_KEY = ("a scenario file cannot load part families (a folder of part files is Python "
                "code, and a scenario is data); pass --parts DIR on the command line instead: "
                "rgmcad --parts DIR COMMAND ...")


def load_scenario(path: str | Path, *, parts_dir: Path | None = None) -> Scenario:
    """Read and check a scenario file. Raises ScenarioError on any bad input.

    ``parts_dir``: the folder of part families (``rgmcad --parts DIR``; default: the shipped
    ones). Its Python files are imported: only the caller chooses it, never the file.
    """
    path = Path(path)
    text = read_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise one_line(ScenarioError(str(path), "", f"not valid TOML: "
                                     f"{toml_error(text, str(exc))}")) from None
    except RecursionError:
        raise ScenarioError(str(path), "", "not valid TOML here: arrays or tables nested too "
                            "deeply to read") from None
    return parse_scenario(data, where=str(path), path=path, parts_dir=parts_dir)


def parse_scenario(data: Mapping, *, where: str = "<scenario>", path: Path | None = None,
                   parts_dir: Path | None = None) -> Scenario:
    """Check a scenario's TOML data (a mapping) and read it; ``where`` names it in errors.

    The part families come from ``parts_dir`` (default: the shipped ones); the scenario keeps
    that registry (``Scenario.families``). Warnings of likely slips of units are logged once
    the whole scenario has loaded.
    """
    try:
        with warnings_after_loading():
            return _parse(data, where, path, parts_dir)
    except ScenarioError as exc:
        raise one_line(exc) from None


def _parse(data, where, path, parts_dir) -> Scenario:
    data = expect(data, dict, where, "")
    if "parts" in data:
        raise ScenarioError(where, "parts", NO_PARTS_KEY)
    check_keys(data, TOP_KEYS, where, "")
    families = load_families(parts_dir)
    if "name" in data:
        name = check_scenario_name(expect(data["name"], str, where, "name"), where)
    else:
        name = check_scenario_name(path.stem if path else "scenario", where, from_file=True)
    settings = _parse_settings(data.get("simulation", {}), where)

    objects: dict[str, SceneObject] = {}
    free: list[FreeParameter] = []
    runs: dict[str, tuple[str, ...]] = {}

    raw_objects = expect(data.get("objects", {}), dict, where, "objects")
    raw_runs = expect(data.get("runs", {}), dict, where, "runs")
    if len(raw_objects) + len(raw_runs) > MAX_BODIES:
        raise ScenarioError(where, "objects", f"{len(raw_objects) + len(raw_runs):,} objects "
                            f"and runs; at most {MAX_BODIES:,} bodies per scenario")
    for obj_name, raw in raw_objects.items():
        key = f"objects.{key_text(obj_name)}"
        check_name(obj_name, where, key)
        raw = expect(raw, dict, where, key)
        check_keys(raw, OBJECT_KEYS, where, key)
        _check_note(raw, where, key)
        part = expect(raw.get("part", None), str, where, f"{key}.part")
        if part == FRAME:
            params = None
            if "params" in raw:
                raise ScenarioError(where, f"{key}.params", "a frame has no parameters")
        else:
            if part not in families:
                allowed = ", ".join(sorted([*families, FRAME]))
                raise ScenarioError(where, f"{key}.part",
                                    f"unknown part {show(part)}; allowed: {allowed}")
            params = families[part].make_params(
                expect(raw.get("params", {}), dict, where, f"{key}.params"),
                where=where, key=f"{key}.params")
            _note_sizes(params, where, f"{key}.params")
        physical = _parse_physical(raw, where, key)
        if part == FRAME and not physical.static:
            raise ScenarioError(where, key, "a frame has no body: remove mass/density")
        if part != FRAME and families[part].infinite and not physical.static:
            raise ScenarioError(where, key, "an infinite plane is always static")
        pose = _parse_pose(raw.get("pose", {}), where, f"{key}.pose")
        objects[obj_name] = SceneObject(obj_name, part, params, physical,
                                        _parse_parent(raw, where, key), pose)
        free.extend(_parse_free(raw.get("free", {}), obj_name, where, f"{key}.free"))

    for run_name, raw in raw_runs.items():
        key = f"runs.{key_text(run_name)}"
        check_name(run_name, where, key)
        if run_name in objects:
            raise ScenarioError(where, key, "a run cannot share its name with an object")
        raw = expect(raw, dict, where, key)
        check_keys(raw, RUN_KEYS, where, key)
        _check_note(raw, where, key)
        pose = _parse_pose(raw.get("pose", {}), where, f"{key}.pose")
        objects[run_name] = SceneObject(run_name, FRAME, None, Physical(),
                                        _parse_parent(raw, where, key), pose)
        free.extend(_parse_free(raw.get("free", {}), run_name, where, f"{key}.free"))
        names = _expand_run(run_name, raw, families, objects, where, key,
                            path.parent if path else Path("."))
        runs[run_name] = tuple(names)
        if len(objects) > MAX_BODIES:
            raise ScenarioError(where, key, f"this run brings the scenario to {len(objects):,} "
                                f"bodies; at most {MAX_BODIES:,} bodies per scenario (objects, "
                                "dominoes and frames)")

    if len(free) > MAX_FREE:
        raise ScenarioError(where, "objects", f"{len(free):,} free parameters; at most "
                            f"{MAX_FREE:,} (the dimension of the design space)")
    _check_parents(objects, runs, where)
    joints = _parse_joints(data.get("joints", []), objects, families, where)
    ropes = parse_ropes(data.get("ropes", {}), objects, where)
    events = parse_events(data.get("events", {}), objects, families, runs, where, settings)
    layouts = _parse_layouts(data.get("layouts", {}), objects, free, where)

    scenario = Scenario(
        name=name, path=path,
        description=expect(data.get("description", ""), str, where, "description"),
        objects=objects, free=tuple(free), joints=joints, events=events, settings=settings,
        layouts=layouts, families=families, runs=runs, ropes=ropes,
    )
    if not events:
        raise ScenarioError(where, "events", "a scenario needs a causal graph of at least one event")
    return scenario


def _parse_parent(raw, where, key) -> str | None:
    parent = raw.get("parent")
    return None if parent is None else expect(parent, str, where, f"{key}.parent")


def _check_note(raw, where, key) -> None:
    """``note``: free text for the reader of the file (read nowhere else)."""
    if "note" in raw:
        expect(raw["note"], str, where, f"{key}.note")


def _note_sizes(params, where, key) -> None:
    """Warn of part parameters in metres (the default unit) that are implausibly large."""
    for f in dataclasses.fields(params):
        value = getattr(params, f.name)
        if (f.metadata.get("unit", "m") == "m" and isinstance(value, float)
                and abs(value) > SIZE.usual[1]):
            warn(f"{where}: {key}.{f.name}: {value:g} m is unusual: {MM_AS_M}")


def _expand_run(run_name, raw, families, objects, where, key, folder) -> list[str]:
    domino = expect(raw.get("domino"), dict, where, f"{key}.domino")
    check_keys(domino, tuple(DOMINO), where, f"{key}.domino")
    size = {}
    for k, spec in DOMINO.items():
        if k not in domino:
            raise ScenarioError(where, f"{key}.domino.{k}", f"a domino needs its {k} "
                                f"({spec.describe(k)})")
        size[k] = spec.read(domino[k], where, f"{key}.domino.{k}")
    if "box" not in families:
        raise ScenarioError(where, f"{key}.domino", "domino runs are made of the part family "
                            "'box', which the parts folder lacks")
    params = families["box"].make_params(
        {"length": size["thickness"], "width": size["width"], "height": size["height"]},
        where=where, key=f"{key}.domino")
    coords = _run_path(raw, where, key, folder)
    check_overlaps(coords, params.length, params.width, where, f"{key}.path")
    tilt = RUN["tilt"].read(raw.get("tilt", 0.0), where, f"{key}.tilt")
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


def _run_path(raw, where, key, folder: Path) -> np.ndarray:
    """(n, 3) domino positions and headings of a run's ``path``, every parameter checked
    against :data:`~rgmcad.scene.schema.PATHS` (and the count bounded) before any is made;
    an SVG file is found relative to ``folder``, the scenario file's."""
    path = expect(raw.get("path"), dict, where, f"{key}.path")
    kind = path.get("kind")
    if not isinstance(kind, str) or kind not in PATHS:
        raise ScenarioError(where, f"{key}.path.kind",
                            f"unknown path {show(kind)}; allowed: {', '.join(PATHS)}")
    table = PATHS[kind]
    check_keys(path, ("kind", *table), where, f"{key}.path")
    args = {k: spec.read(path[k], where, f"{key}.path.{k}")
            for k, spec in table.items() if k in path}
    if "file" in args:
        args["file"] = str(folder / args["file"])
    make = PATH_MAKERS[kind]
    for p in inspect.signature(make).parameters.values():
        if p.default is p.empty and p.name not in args:
            raise ScenarioError(where, f"{key}.path.{p.name}", f"a {kind} path needs "
                                f"{p.name} ({table[p.name].describe(p.name)})")
    try:
        n = COUNTERS[kind](**args) if kind in COUNTERS else 0
        coords = None if n > MAX_RUN else make(**args)
    except ValueError as exc:
        raise ScenarioError(where, f"{key}.path", f"bad {kind} path: {exc}") from None
    if coords is None:
        raise ScenarioError(where, f"{key}.path.spacing", f"this spacing gives {n:,} dominoes; "
                            f"at most {MAX_RUN:,} per run")
    if len(coords) > MAX_RUN:
        raise ScenarioError(where, f"{key}.path", f"{len(coords):,} dominoes; at most "
                            f"{MAX_RUN:,} per run")
    if not np.all(np.isfinite(coords)):
        raise ScenarioError(where, f"{key}.path", f"this {kind} path gives positions that are "
                            "not finite numbers")
    gaps = np.linalg.norm(np.diff(coords[:, :2], axis=0), axis=1)
    if len(gaps) and gaps.min() < 1e-6:
        raise ScenarioError(where, f"{key}.path", f"this {kind} path stands two dominoes in one "
                            "place (a path of no length: an arc from an angle to itself?)")
    return coords


def _tilted(pose, thickness, height, tilt_deg):
    """Pose of a domino leaned forward by ``tilt_deg`` about its bottom front edge.

    The paper's code turned the domino about a point one full thickness ahead and one full
    height below its centre, which lifts it off the ground; we turn it about the real edge.
    """
    from rgmcad.geometry import matmul, pose6_of, pose_matrix, translation

    standing = pose_matrix(pose)
    edge = np.array([thickness / 2, 0.0, -height / 2])
    lean = matmul(matmul(translation(edge), pose_matrix((0, 0, 0, 0, 0, tilt_deg))),
                  translation(-edge))
    return tuple(float(v) for v in pose6_of(matmul(standing, lean)))


def _parse_settings(raw, where) -> SimulationSettings:
    raw = expect(raw, dict, where, "simulation")
    check_keys(raw, SIMULATION_KEYS, where, "simulation")
    settings = SimulationSettings(**{k: SIMULATION[k].read(v, where, f"simulation.{k}")
                                     for k, v in raw.items()})
    steps = settings.duration / settings.timestep
    if steps < 1:
        raise ScenarioError(where, "simulation.duration", f"{settings.duration:g} s is shorter "
                            f"than one time step ({settings.timestep:g} s)")
    if steps > MAX_STEPS:
        raise ScenarioError(where, "simulation.duration", f"{settings.duration:g} s in steps of "
                            f"{settings.timestep:g} s is {steps:,.0f} steps; at most "
                            f"{MAX_STEPS:,} (shorten duration or lengthen timestep)")
    return settings


def _parse_physical(raw, where, key) -> Physical:
    values = {k: PHYSICAL[k].read(raw[k], where, f"{key}.{k}") for k in PHYSICAL_KEYS if k in raw}
    if "mass" in values and "density" in values:
        raise ScenarioError(where, key, "give mass or density, not both")
    return Physical(**values)


def _parse_pose(raw, where, key) -> tuple[float, ...]:
    raw = expect(raw, dict, where, key)
    check_keys(raw, POSE_KEYS, where, key)
    return tuple(POSE[k].read(raw.get(k, 0.0), where, f"{key}.{k}") for k in POSE_KEYS)


def _parse_free(raw, obj_name, where, key) -> list[FreeParameter]:
    raw = expect(raw, dict, where, key)
    check_keys(raw, POSE_KEYS, where, key)
    out = []
    for component in POSE_KEYS:  # canonical order, whatever the file's order
        if component not in raw:
            continue
        rng, spec, k = raw[component], POSE[component], f"{key}.{component}"
        if not isinstance(rng, list) or len(rng) != 2:
            raise ScenarioError(where, k, f"expected a range [min, max], each "
                                f"{spec.describe(component)}, got {show(rng)}")
        low, high = (spec.read(v, where, f"{k}[{i}]") for i, v in enumerate(rng))
        if not high - low >= MIN_RANGE:
            raise ScenarioError(where, k, f"range min must be < max (by at least "
                                f"{MIN_RANGE:g} {spec.unit}), got [{low:g}, {high:g}]")
        if spec.unit == "deg" and reads_as_radians(low, high):
            warn(f"{where}: {k}: a range of {high - low:g} deg is unusual: radians written as "
                 f"degrees? ([{low:g}, {high:g}] rad is [{math.degrees(low):.1f}, "
                 f"{math.degrees(high):.1f}] deg)")
        out.append(FreeParameter(obj_name, component, low, high))
    return out


def _check_parents(objects, runs, where):
    graph = nx.DiGraph()
    for name, obj in objects.items():
        graph.add_node(name)
        if obj.parent is not None:
            if obj.parent not in objects:
                key = f"runs.{name}.parent" if name in runs else f"objects.{name}.parent"
                raise ScenarioError(where, key, f"unknown parent {show(obj.parent)}; "
                                    "allowed: any object or run name")
            graph.add_edge(obj.parent, name)
    if not nx.is_directed_acyclic_graph(graph):
        cycle = " -> ".join(e[0] for e in nx.find_cycle(graph))
        raise ScenarioError(where, "objects", f"the parents form a cycle: {cycle}")
    chain = nx.dag_longest_path(graph)
    if len(chain) - 1 > MAX_DEPTH:
        raise ScenarioError(where, "objects", f"a chain of {len(chain) - 1:,} parents "
                            f"({chain[0]} -> ... -> {chain[-1]}); at most {MAX_DEPTH:,} levels")


def _parse_joints(raw, objects, families, where) -> tuple[Joint, ...]:
    raw = expect(raw, list, where, "joints")
    if len(raw) > MAX_JOINTS:
        raise ScenarioError(where, "joints", f"{len(raw):,} joints; at most {MAX_JOINTS:,}")
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
            raise ScenarioError(where, f"{key}.kind",
                                f"unknown joint {show(kind)}; allowed: weld, hinge")
        names = expect(j.get("objects"), list, where, f"{key}.objects")
        wanted = (2,) if kind == "weld" else (1, 2)
        if len(names) not in wanted:
            raise ScenarioError(where, f"{key}.objects",
                                "a weld joins two objects; a hinge names one (hinged to the "
                                "world) or two (the moving one first)")
        for n in names:
            if not isinstance(n, str) or n not in objects or objects[n].part == FRAME:
                raise ScenarioError(where, f"{key}.objects", f"unknown body {show(n)}")
        if len(set(names)) != len(names):
            raise ScenarioError(where, f"{key}.objects", "a joint joins two different bodies")
        if kind == "hinge" and objects[names[0]].physical.static:
            raise ScenarioError(where, f"{key}.objects", f"{show(names[0])} has no mass or "
                                "density, so it never moves: give it one to swing on the "
                                "hinge (the moving body comes first)")
        vec = {k: JOINT[k].read(j[k], where, f"{key}.{k}") for k in JOINT if k in j}
        joints.append(Joint(kind, tuple(names), **vec))
    return tuple(joints)


def _parse_layouts(raw, objects, free, where) -> dict[str, dict[str, float]]:
    raw = expect(raw, dict, where, "layouts")
    if len(raw) > MAX_LAYOUTS:
        raise ScenarioError(where, "layouts", f"{len(raw):,} layouts; at most {MAX_LAYOUTS:,}")
    by_name = {f.name: f for f in free}
    layouts = {"initial": {f.name: objects[f.object].pose[POSE_KEYS.index(f.component)]
                           for f in free}}
    for layout_name, table in raw.items():
        key = f"layouts.{key_text(layout_name)}"
        check_name(layout_name, where, key)
        table = expect(table, dict, where, key)
        values = dict(layouts["initial"])
        for obj_name, comps in table.items():
            comps = expect(comps, dict, where, f"{key}.{key_text(obj_name)}")
            for comp, value in comps.items():
                pname = f"{obj_name}.{comp}"
                if pname not in by_name:
                    raise ScenarioError(where, f"{key}.{key_text(obj_name)}.{key_text(comp)}",
                                        "not a free parameter; allowed: " + ", ".join(by_name))
                values[pname] = POSE[comp].read(value, where, f"{key}.{pname}")
        layouts[layout_name] = values
    return layouts
