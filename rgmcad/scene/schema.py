"""Every number a scenario file may hold, written once: its unit, the range it must lie in,
and the usual range outside which it is probably a slip of units (a warning, never an error);
and how big a scenario may grow.

The loader reads every number through these specs (:meth:`Number.read`): a value that is not
a number (a TOML boolean is not), not finite, or out of range is refused with one line naming
the file, the key and what is allowed. Every range is finite, so a value that passes is a
finite float (or a bounded int) whatever the file holds. The documentation's table of keys
(the generated reference page of scenario files) is :func:`markdown`.

Warnings go through :mod:`logging` (the library never prints) and only once the whole file
has loaded (:func:`warnings_after_loading`): a refused file gives its one error line alone.
"""

from __future__ import annotations

import logging
import math
import reprlib
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass

from rgmcad.errors import ScenarioError, printable

log = logging.getLogger("rgmcad.scene")

# --- how big a scenario may grow (each limit is named in the error that enforces it) ---------

MAX_FILE_BYTES = 2 * 2**20
"""Bytes of a scenario file (2 MiB: a scenario of the largest size below is under 1 MiB)."""
MAX_BODIES = 2000
"""Objects of one scenario, dominoes and frames included."""
MAX_RUN = 1000
"""Dominoes of one run."""
MAX_EVENTS = 500
MAX_JOINTS = 1000
MAX_FREE = 100
"""Free parameters: the dimension of the design space."""
MAX_LAYOUTS = 1000
MAX_DEPTH = 100
"""Levels of parents above an object (poses compose down the chain)."""
MAX_POINTS = 1000
"""Corners of a polyline path."""
MAX_NAME = 100
"""Characters of a name (scenario, object, run, event, layout)."""
MAX_STEPS = 1_000_000
"""Simulation steps of one run: duration / timestep."""
MAX_ROPES = 100
MAX_PULLEYS = 100
"""Pulley points of one rope."""
MIN_RANGE = 1e-6
"""Narrowest free range (m or deg): a narrower one maps tiny moves to huge design vectors."""
TOUCHING = 2e-4
"""Deepest overlap (m) of two dominoes of one run still counted as touching (the layout
validity check's tolerance)."""
MAX_RUN_OVERLAPS = 100
"""Pairs of dominoes of one run that overlap (deeper than :data:`TOUCHING`): a sharp corner
makes a few, which the validity check reports; dominoes inside each other make up to half a
million, each an exact intersection for that check (minutes), and are refused."""
MAX_SVG_BYTES = 2 * 2**20
"""Bytes of the SVG drawing of a run (its XML entities expanded)."""
MAX_SVG_ELEMENTS = 10_000
"""Groups, paths and other elements of a drawing, each copy a ``<use>`` makes counted."""
MAX_SVG_DEPTH = 100
"""Levels of groups and ``<use>`` references in a drawing."""
MAX_SVG_NUMBERS = 100_000
"""Numbers of a drawing's path data and transforms, and its closings (``z``), every copy a
``<use>`` makes counted: the work of reading the drawing (a few seconds at most)."""
MAX_SVG_CLOSES = 100
"""Closings (``z``) of one piece of a path (from one ``M`` to the next)."""
MAX_SVG_LENGTH = 100.0
"""Metres of the path a run follows."""
MAX_SVG_REACH = 1000.0
"""How far (m) any point of the followed path, or a control point of its curves, may lie
from the drawing's origin (the reach of a position); also the largest width or height of a
drawing."""

LIMITS = {
    "file size": "2 MiB",
    "bodies (objects, dominoes and frames)": f"{MAX_BODIES:,}",
    "dominoes per run": f"{MAX_RUN:,}",
    "overlapping pairs of dominoes in one run": f"{MAX_RUN_OVERLAPS:,}",
    "events": f"{MAX_EVENTS:,}",
    "joints": f"{MAX_JOINTS:,}",
    "ropes": f"{MAX_ROPES:,}",
    "pulleys per rope": f"{MAX_PULLEYS:,}",
    "free parameters": f"{MAX_FREE:,}",
    "layouts": f"{MAX_LAYOUTS:,}",
    "levels of parents": f"{MAX_DEPTH:,}",
    "polyline points": f"{MAX_POINTS:,}",
    "characters of a name": f"{MAX_NAME:,}",
    "simulation steps (duration / timestep)": f"{MAX_STEPS:,}",
    "size of a run's SVG drawing": f"{MAX_SVG_BYTES // 2**20} MiB",
    "elements of a drawing (every <use> copy counted)": f"{MAX_SVG_ELEMENTS:,}",
    "levels of groups and <use> references in a drawing": f"{MAX_SVG_DEPTH:,}",
    "numbers of a drawing's paths and transforms": f"{MAX_SVG_NUMBERS:,}",
    "closings (z) of one piece of a path": f"{MAX_SVG_CLOSES:,}",
    "length of a drawn path": f"{MAX_SVG_LENGTH:g} m",
    "reach of a drawn path from the drawing's origin": f"{MAX_SVG_REACH:,g} m",
}

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxdict, _REPR.maxtuple = 2, 4, 4, 4
_REPR.maxstring, _REPR.maxother, _REPR.maxlong = 40, 40, 40


def show(value) -> str:
    """A short one-line repr of a value read from a file (however long or deep it is)."""
    return _REPR.repr(value)


def _fmt(v: float) -> str:
    return f"{int(v):,}" if float(v).is_integer() and abs(v) < 1e7 else f"{v:g}"


# --- the specs --------------------------------------------------------------------------------


@dataclass(frozen=True)
class Number:
    """A number in ``unit`` that must lie in [low, high] (``open_low`` / ``open_high``: the
    bound itself is refused); outside ``usual`` it is accepted with a warning that says which
    slip it probably is (``slip = (below, above)``)."""

    unit: str
    low: float
    high: float
    open_low: bool = False
    open_high: bool = False
    integer: bool = False
    usual: tuple[float, float] = (-math.inf, math.inf)
    slip: tuple[str, str] = ("", "")
    why: str = ""  # why the limit, said in the error

    def describe(self, name: str = "x") -> str:
        kind = "an integer" if self.integer else "a number"
        unit = f" ({self.unit})" if self.unit else ""
        lo, hi = ("<" if self.open_low else "<="), ("<" if self.open_high else "<=")
        why = f"; {self.why}" if self.why else ""
        return f"{kind}{unit}, {_fmt(self.low)} {lo} {name} {hi} {_fmt(self.high)}{why}"

    def accepts(self, value) -> bool:
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False
        if self.integer and not isinstance(value, int):
            return False
        if isinstance(value, float) and not math.isfinite(value):
            return False
        above = value > self.low if self.open_low else value >= self.low
        below = value < self.high if self.open_high else value <= self.high
        return above and below

    def read(self, value, where: str, key: str) -> float | int:
        """``value`` as a float (an int for integers), or ScenarioError naming ``key``."""
        if not self.accepts(value):
            name = key.rpartition(".")[2].partition("[")[0] or "x"
            raise ScenarioError(where, key, f"expected {self.describe(name)}, got {show(value)}")
        low, high = self.usual
        if not low <= abs(value) <= high:
            slip = self.slip[0] if abs(value) < low else self.slip[1]
            warn(f"{where}: {key}: {_fmt(value)} {self.unit} is unusual: {slip}")
        return value if self.integer else float(value)


@dataclass(frozen=True)
class Flag:
    """true or false."""

    def describe(self, name: str = "x") -> str:
        return "true or false"

    def read(self, value, where: str, key: str) -> bool:
        if not isinstance(value, bool):
            raise ScenarioError(where, key, f"expected true or false, got {show(value)}")
        return value


@dataclass(frozen=True)
class Vector:
    """A list of ``size`` numbers, each a ``number``; ``nonzero``: its length at least 1e-6."""

    number: Number
    size: int
    nonzero: bool = False

    def describe(self, name: str = "x") -> str:
        what = f"a list of {self.size}: each {self.number.describe('x')}"
        return what + (", not all zero" if self.nonzero else "")

    def read(self, value, where: str, key: str) -> tuple[float, ...]:
        if not isinstance(value, list) or len(value) != self.size:
            raise ScenarioError(where, key, f"expected {self.describe()}, got {show(value)}")
        out = tuple(self.number.read(v, where, f"{key}[{i}]") for i, v in enumerate(value))
        if self.nonzero and math.hypot(*out) < 1e-6:
            raise ScenarioError(where, key, f"expected a non-zero vector (length at least "
                                f"1e-06), got {show(value)}")
        return out


@dataclass(frozen=True)
class Text:
    """A string of 1 to ``longest`` printable characters (a file name, an id)."""

    what: str
    longest: int = 1000

    def describe(self, name: str = "x") -> str:
        return f"a string ({self.what}), 1 to {self.longest:,} characters"

    def read(self, value, where: str, key: str) -> str:
        if (not isinstance(value, str) or not 1 <= len(value) <= self.longest
                or not value.isprintable()):
            raise ScenarioError(where, key, f"expected {self.describe()}, got {show(value)}")
        return value


@dataclass(frozen=True)
class Points:
    """A list of ``low``..``high`` [x, y] pairs."""

    point: Vector
    low: int
    high: int

    def describe(self, name: str = "x") -> str:
        return (f"a list of {self.low} to {self.high:,} [x, y] points, each coordinate "
                f"{self.point.number.describe('x')}")

    def read(self, value, where: str, key: str) -> list[tuple[float, ...]]:
        if not isinstance(value, list) or not self.low <= len(value) <= self.high:
            raise ScenarioError(where, key, f"expected {self.describe()}, got {show(value)}")
        return [self.point.read(p, where, f"{key}[{i}]") for i, p in enumerate(value)]


# --- the table ------------------------------------------------------------------------------

MM_AS_M = "millimetres written as metres?"
SIZE = Number("m", 1e-5, 100, usual=(0, 2), slip=("", MM_AS_M))
"""A size: a domino's, a path's length or radius."""
SPREAD = Number("m", 0, 100)
"""A width or length that may be zero (a wave or a branch with no sideways swing, a line of
one domino)."""
POSITION = Number("m", -1000, 1000, usual=(0, 10), slip=("", MM_AS_M))
ANGLE = Number("deg", -360, 360)
COUNT = Number("", 1, MAX_RUN, integer=True, why=f"at most {MAX_RUN:,} dominoes per run")
XY = Vector(POSITION, 2)

SIMULATION = {
    "timestep": Number("s", 1e-5, 0.05),
    "duration": Number("s", 0, 600, open_low=True),
    "event_timeout": Number("s", 0, 600, open_low=True),
    "gravity": Number("m/s^2", 0, 100, open_low=True),
    "solver_iterations": Number("", 1, 1000, integer=True),
    "erp": Number("", 0, 1, open_low=True),
    "contact_erp": Number("", 0, 1, open_low=True),
    "friction_erp": Number("", 0, 1, open_low=True),
    "split_impulse": Flag(),
    "contact_breaking_threshold": Number("m", 0, 1, open_low=True),
    "restitution_velocity_threshold": Number("m/s", 0, 100),
    "convex_margin": Number("m", 0, 0.1, open_low=True),
    "ccd": Flag(),
    "solver_residual_threshold": Number("N^2 s^2", 0, 1),
}
"""``[simulation]``: one spec per field of :class:`~rgmcad.scene.model.SimulationSettings`."""

PHYSICAL = {
    "mass": Number("kg", 1e-6, 1000, usual=(0, 5), slip=("", "grams written as kilograms?")),
    "density": Number("kg/m^3", 1, 100_000, usual=(50, 25_000),
                      slip=("grams per cm^3 written as kg/m^3? (water is 1000)",
                            "denser than any metal: grams per m^3?")),
    "friction": Number("", 0, 10),
    "restitution": Number("", 0, 1),
    "linear_damping": Number("", 0, 1),
    "angular_damping": Number("", 0, 1),
    "rolling_friction": Number("", 0, 10),
    "spinning_friction": Number("", 0, 10),
}
"""An object's or a run's physical properties (:class:`~rgmcad.scene.model.Physical`)."""

POSE = {"x": POSITION, "y": POSITION, "z": POSITION,
        "heading": ANGLE, "pitch": ANGLE, "roll": ANGLE}
"""A pose component; also each bound of a free range and a layout's value."""

RUN = {"tilt": Number("deg", 0, 90, open_high=True)}
DOMINO = {"thickness": SIZE, "width": SIZE, "height": SIZE}

PATHS = {
    "line": {"count": COUNT, "length": SPREAD, "origin": XY, "angle": ANGLE},
    "arc": {"count": COUNT, "radius": SIZE, "start": Number("deg", -720, 720),
            "end": Number("deg", -720, 720), "center": XY},
    "wave": {"count": COUNT, "length": SIZE, "width": SPREAD, "origin": XY, "angle": ANGLE},
    "branch": {"arm_count": Number("", 2, MAX_RUN // 3, integer=True,
                                   why=f"3 x arm_count <= {MAX_RUN:,} dominoes per run"),
               "length": SIZE, "width": SPREAD, "origin": XY, "angle": ANGLE},
    "x_switch": {"count": Number("", 7, (MAX_RUN + 1) // 2, integer=True,
                                 why=f"2 x count - 1 <= {MAX_RUN:,} dominoes per run; odd"),
                 "width": SIZE, "origin": XY, "angle": ANGLE},
    "polyline": {"points": Points(XY, 2, MAX_POINTS), "count": COUNT, "spacing": SIZE},
    "svg": {"file": Text("an SVG file, relative to the scenario file"),
            "element": Text("the id of a <path> in it; default: its first path"),
            "count": COUNT, "spacing": SIZE},
}
"""``path = { kind = ..., ... }`` of a run: the parameters of each kind."""

EVENT_PARAMS = {
    "tolerance": Number("m", 0, 1),
    "min_angvel": Number("rad/s", 0, 10_000),
    "min_linvel": Number("m/s", 0, 1000),
    "max_linvel": Number("m/s", 0, 1000, open_low=True),
    "max_angvel": Number("rad/s", 0, 10_000, open_low=True),
    "position_tolerance": Number("m", 0, 10, open_low=True),
    "angle_tolerance": Number("deg", 0, 180, open_low=True),
    "angle": Number("deg", 0, 180, open_low=True),
}
"""The parameters of the event types (:data:`~rgmcad.scene.eventspec.EVENT_TYPES`)."""

EVENT = {"timeout": Number("s", 0, 600, open_low=True), "hold": Number("s", 0, 600)}
POINT = {"x": POSITION, "y": POSITION, "z": POSITION}
JOINT = {"point": Vector(POSITION, 3), "axis": Vector(Number("", -1000, 1000), 3, nonzero=True)}
ROPE = {"length": Number("m", 1e-4, 100, usual=(0, 10), slip=("", MM_AS_M)),
        "slack": Number("m", 0, 100, usual=(0, 10), slip=("", MM_AS_M)),
        "point": Vector(POSITION, 3)}
"""``[ropes.NAME]``: the rope's length or slack, and the ``point`` of each end and pulley."""
VECTOR = Number("", 0, 1)
"""Each entry of a design vector (``--vector``, a layout file's ``vector``)."""


def rows() -> Iterator[tuple[str, str, object]]:
    """(where, keys, spec) of every number of a scenario file; keys sharing a spec grouped."""
    groups: list[tuple[str, list[str], object]] = []

    def add(where, key, spec):
        for w, keys, sp in groups:
            if w == where and sp == spec:
                keys.append(key)
                return
        groups.append((where, [key], spec))

    for k, s in SIMULATION.items():
        add("`[simulation]`", k, s)
    for k, s in PHYSICAL.items():
        add("objects, runs", k, s)
    for k, s in POSE.items():
        add("`pose`, each bound of `free`, layouts", k, s)
    for k, s in RUN.items():
        add("runs", k, s)
    for k, s in DOMINO.items():
        add("runs: `domino`", k, s)
    by_key: dict[str, list[str]] = {}
    for kind, table in PATHS.items():
        for k, s in table.items():
            by_key.setdefault((k, s), []).append(kind)
    for (k, s), kinds in by_key.items():
        add(f"runs: `path` ({', '.join(kinds)})", k, s)
    for k, s in (*EVENT.items(), *EVENT_PARAMS.items()):
        add("events", k, s)
    for k, s in POINT.items():
        add("events: `point`", k, s)
    for k, s in JOINT.items():
        add("joints", k, s)
    for k, s in ROPE.items():
        add("ropes", k, s)
    for where, keys, spec in groups:
        yield where, ", ".join(f"`{k}`" for k in keys), spec


def markdown() -> str:
    """The table of every number's unit and allowed range, and the size limits (the
    reference page of scenario files shows it)."""
    lines = ["| in | keys | allowed | usual (a warning outside) |", "|---|---|---|---|"]
    for where, keys, spec in rows():
        usual = getattr(spec, "usual", (-math.inf, math.inf))
        if usual == (-math.inf, math.inf):
            note = ""
        elif usual[0] <= 0:
            note = f"up to {_fmt(usual[1])} {spec.unit}"
        else:
            note = f"{_fmt(usual[0])} to {_fmt(usual[1])} {spec.unit}"
        lines.append(f"| {where} | {keys} | {spec.describe()} | {note} |")
    lines += ["", "| limit | at most |", "|---|---|"]
    lines += [f"| {what} | {n} |" for what, n in LIMITS.items()]
    return "\n".join(lines)


# --- warnings, once the file has loaded ------------------------------------------------------

_PENDING: ContextVar[list[str] | None] = ContextVar("rgmcad_scene_warnings", default=None)


def warn(message: str) -> None:
    """A warning about a value that loads but is probably a slip (logged once loading ends;
    a file's name and keys in it shown :func:`~rgmcad.errors.printable`)."""
    message = printable(message)
    pending = _PENDING.get()
    if pending is None:
        log.warning(message)
    elif message not in pending:
        pending.append(message)


@contextmanager
def warnings_after_loading():
    """Hold :func:`warn`'s warnings back until the block ends; drop them if it raises."""
    token = _PENDING.set([])
    try:
        yield
        pending = _PENDING.get()
    finally:
        _PENDING.reset(token)
    for message in pending:
        log.warning(message)
