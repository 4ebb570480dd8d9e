"""``reference/scenario.md`` and ``reference/events.md``: the tables and keys of a scenario
file, from the loader's lists of keys, the defaults of :mod:`rgmcad.scene.model` and the
schema of every number (:mod:`rgmcad.scene.schema`); the prose of each key is written here,
once, and a key without it (or prose of a key that went) fails the build."""

from __future__ import annotations

import dataclasses
import inspect
import re

from rgmcad.geometry import POSE_KEYS
from rgmcad.reference.text import cell, code, described, rst, sentence, table
from rgmcad.scene import schema
from rgmcad.scene.eventspec import ENDS, EVENT_TYPES, Negation
from rgmcad.scene.loader import OBJECT_KEYS, PATH_MAKERS, RUN_KEYS, TOP_KEYS
from rgmcad.scene.loader_events import EVENT_COMMON_KEYS, EVENT_POINT_KEYS
from rgmcad.scene.loader_ropes import POINT_KEYS as ROPE_POINT_KEYS
from rgmcad.scene.loader_ropes import ROPE_KEYS
from rgmcad.scene.model import (
    FRAME,
    PHYSICAL_KEYS,
    SIMULATION_KEYS,
    Joint,
    Physical,
    SimulationSettings,
)

TOP = {
    "name": f"the scenario's name, 1 to {schema.MAX_NAME} ASCII letters, digits, `_`, `-` or "
            "`.`: it names output folders. Default: the file's name without `.toml`",
    "description": "one line saying what the contraption does (`rgmcad check` prints it)",
    "simulation": "`[simulation]`: the physics engine's settings; each has a default",
    "objects": "`[objects.NAME]`: the parts, each a part family with its parameters, "
               "physical properties and a pose relative to its parent",
    "runs": "`[runs.NAME]`: rows of dominoes generated along a path; domino `i` is the body "
            "`NAME[i]` (`NAME[-1]`: the last)",
    "joints": "`[[joints]]`: welds and hinges between objects",
    "ropes": "`[ropes.NAME]`: ropes tied between two points, over pulleys",
    "events": "`[events.NAME]`: the causal graph, the events that must happen and what each "
              "waits for (see [Events](events.md)); at least one",
    "layouts": "`[layouts.NAME]`: named values of the free parameters",
}
PLACED = {
    "parent": "the object or run whose frame `pose` is relative to (default: the world)",
    "pose": f"`{{ {', '.join(POSE_KEYS)} }}` in m and degrees, relative to the parent; each 0 "
            "when left out. The angles turn the part as Rz(heading) Rx(pitch) Ry(roll)",
    "free": "the free parameters, `{ COMPONENT = [min, max] }` for pose components the "
            "optimiser may move, in m or degrees; together they make the design space",
    "note": "free text for the reader of the file (read nowhere else)",
}
OBJECT = {
    "part": f"the part family (see [Part families](parts.md)), or `\"{FRAME}\"`: a frame, a "
            "pose with no body that other objects take as parent",
    "params": "the part family's parameters, as a table (see [Part families](parts.md))",
    **PLACED,
}
RUN = {
    "domino": f"`{{ {', '.join(schema.DOMINO)} }}` of every domino, m, all needed; dominoes "
              "are parts of the family `box`",
    "path": "`{ kind = \"...\", ... }`: where the dominoes stand, in the run's frame (kinds "
            "below)",
    "tilt": "degrees the first domino leans forward, about its bottom front edge (default 0)",
    **PLACED,
}
ROPE = {
    "ends": "the two points the rope is tied to; at least one on a moving body",
    "pulleys": "the points it runs over, in order, each on a static object or a frame, or in "
               "the world (default: none)",
    "length": "its length, m; or `slack`, not both",
    "slack": "without `length`: the rope is as long as the path through its points in each "
             "layout, plus this (default 0), so it fits every layout",
    "note": PLACED["note"],
}
ROPE_POINT = {"object": "the object (a body or a frame) the point belongs to; left out: the "
                        "world",
              "point": "`[x, y, z]` in m, in the part frame of `object` (default: its origin)"}
EVENT = {
    "type": "the event type (below)",
    "after": "the events it waits for, by name; the one event without `after` is the root, "
             "which wakes at t = 0",
    "join": "`\"all\"` (default): it wakes when every event in `after` has succeeded; "
            "`\"any\"`: when the first of them has",
    # Negation's docstring, without the enum's names a file never writes
    "negate": re.sub(r"`[A-Z]+` \((`[^`]*`)\)", r"\1", " ".join(
        rst(line.strip(" *")) for line in Negation.__doc__.split("\n\n", 1)[1].splitlines()
        if line.strip())),
    "hold": "s the condition must hold in a row before the event succeeds (default 0)",
    "timeout": "s the event may stay awake before it fails (default: `[simulation]` "
               "`event_timeout`)",
    "description": "free text; the 3D replay pages show it over the event's name",
}
POINT = {"point": "`{ x, y, z }`: the point of the body whose motion counts (default: its "
                  "centre of mass), m in its part frame; a missing coordinate is 0",
         "end": "the centre of one face of the body's bounding box: "
                + ", ".join(f"`\"{e}\"`" for e in ENDS)}


def _spec(spec) -> str:
    return spec.describe() if spec is not None else ""


def _defaults(cls) -> dict:
    return {f.name: f.default for f in dataclasses.fields(cls)
            if f.default is not dataclasses.MISSING}


def _keys(keys, docs, what, specs=None, defaults=None) -> str:
    """A table of ``keys``: the prose of each (``docs``; None: no such column), the range its
    spec allows and its default."""
    specs, defaults = specs or {}, defaults or {}
    rows = []
    for key, text in (described(keys, docs, what) if docs is not None else
                      [(k, None) for k in keys]):
        default = defaults.get(key)
        rows.append((f"`{key}`", *([] if text is None else [text]), _spec(specs.get(key)),
                     "" if default is None else code(default)))
    return table(["key", *([] if docs is None else ["what it is"]), "allowed", "default"], rows)


def _paths() -> list[str]:
    out = []
    for kind, params in schema.PATHS.items():
        make = PATH_MAKERS[kind]
        signature = inspect.signature(make).parameters
        rows = []
        for key, spec in params.items():
            default = signature[key].default if key in signature else inspect.Parameter.empty
            given = ("needed" if default is inspect.Parameter.empty
                     else "optional" if default is None else code(default))
            rows.append((f"`{key}`", spec.describe(), given))
        first = rst((make.__doc__ or "").strip().split("\n\n")[0])
        out += [f"#### `kind = \"{kind}\"`", "", cell(" ".join(first.split())), "",
                table(["key", "allowed", "default"], rows), ""]
    return out


def page() -> str:
    settings = " ".join(rst(SimulationSettings.__doc__).split())
    return "\n".join([
        "# Scenario files", "",
        "A scenario file is a TOML file that describes a contraption: its parts, where they "
        "stand and which of those places the optimiser may move, and the chain of events it "
        "must go through. Lengths are in metres, masses in kilograms, times in seconds and "
        "angles in degrees. `rgmcad check FILE` reads a file and says what is wrong, naming "
        "the key and what is allowed.", "",
        "## Top-level keys", "",
        table(["key", "what it holds"], [(f"`{k}`", t) for k, t in described(
            TOP_KEYS, TOP, "top-level keys")]), "",
        "## `[simulation]`", "",
        cell(settings), "",
        _keys(SIMULATION_KEYS, None, "[simulation]", schema.SIMULATION,
              _defaults(SimulationSettings)), "",
        "## `[objects.NAME]`", "",
        _keys([k for k in OBJECT_KEYS if k not in PHYSICAL_KEYS], OBJECT, "objects"), "",
        "The physical properties of the object's main body. " + cell(" ".join(
            rst(Physical.__doc__).split("\n\n")[1].split())) + " Give `mass` or `density`, "
        "not both.", "",
        _keys(PHYSICAL_KEYS, None, "physical properties", schema.PHYSICAL,
              _defaults(Physical)), "",
        "## `[runs.NAME]`", "",
        "A run is a frame: its dominoes stand along `path` in the run's own frame, so `pose` "
        "and `free` move the whole row, and its physical properties (the keys of objects "
        f"above: {', '.join(f'`{k}`' for k in PHYSICAL_KEYS)}) are each domino's.", "",
        _keys([k for k in RUN_KEYS if k not in PHYSICAL_KEYS], RUN, "runs", schema.RUN), "",
        "### Paths", "", *_paths(),
        "## `[[joints]]`", "",
        "Each joint is a table with `kind`, `\"weld\"` (`objects`: two bodies that move as "
        "one) or `\"hinge\"` (`objects`: one body, hinged to the world, or two, the moving one "
        "first, which turns about `axis` through `point`, both in its own frame).", "",
        _keys(list(schema.JOINT), {"point": "the hinge's point, m", "axis": "the hinge's axis"},
              "joints", schema.JOINT, _defaults(Joint)), "",
        "## `[ropes.NAME]`", "",
        _keys(ROPE_KEYS, ROPE, "ropes", schema.ROPE), "",
        "Each end and pulley is a table:", "",
        _keys(ROPE_POINT_KEYS, ROPE_POINT, "rope points", {"point": schema.ROPE["point"]}), "",
        "## `[layouts.NAME]`", "",
        "A layout gives values to free parameters, `OBJECT = { COMPONENT = value }`; the ones "
        "it leaves out keep the value of the pose as written. The layout `initial`, every pose "
        "as written, is always there. `--layout NAME` of the commands picks one.", "",
        "## Every number", "",
        "The unit and allowed range of every number in a scenario file (a value outside the "
        "usual range loads, with a warning that it is probably a slip of units), and how big "
        "a scenario may grow.", "",
        _html_safe(schema.markdown()), ""])


def _html_safe(markdown_table: str) -> str:
    """A markdown table with each cell made :func:`cell`-safe (its pipes kept)."""
    return "\n".join("|".join(cell(c) for c in line.split("|"))
                     for line in markdown_table.splitlines())


def events_page() -> str:
    out = ["# Events", "",
           "The `[events]` of a scenario file are its causal graph: each event names its "
           "type, the bodies it watches and its thresholds, and waits for the events in its "
           "`after`. The graph is acyclic with one root. An event that wakes succeeds when its "
           "condition holds, and fails when it stays awake longer than its timeout; the run "
           "succeeds when every last event (one no other waits for) has. Bodies are named as "
           "objects (`ball`), run dominoes (`run[0]`, `run[-1]`) or a part's other bodies "
           "(`lever.axle`).", "",
           "## Keys of every event", "",
           _keys(EVENT_COMMON_KEYS, EVENT, "events", schema.EVENT), "",
           "Types that watch a body's motion (marked below) also take one of:", "",
           _keys(EVENT_POINT_KEYS, POINT, "event points"), "",
           "## Types", ""]
    for name, kind in EVENT_TYPES.items():
        rows = [(f"`{role}`", "a body", "", "needed") for role in kind.roles]
        rows += [(f"`{p}`", "", schema.EVENT_PARAMS[p].describe(),
                  "needed" if d is None else code(d)) for p, d in kind.params.items()]
        out += [f"### `{name}`", "", cell(sentence(rst(kind.doc))), ""]
        if kind.takes_point:
            out += ["Takes `point` or `end`.", ""]
        out += [table(["key", "what it is", "allowed", "default"], rows), ""]
    return "\n".join(out)
