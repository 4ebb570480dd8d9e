"""The printing commands: ``rgmcad template`` and ``rgmcad verify-print``.

``rgmcad template SCENARIO --layout NAME|FILE --out DIR`` poses a layout, turns every body
of the scene into a :class:`rgmcad.printing.template.PlacedPart` (base planes become
:class:`rgmcad.printing.template.BasePlane`, never drawn) and writes ``DIR/template.pdf`` (tiled,
tagged sheets) and ``DIR/template.svg`` (1:1, millimetres) with
:func:`rgmcad.printing.template.make_template`. ``rgmcad verify-print IMAGE`` measures the scale a
sheet was printed at with :func:`rgmcad.printing.check.verify_print`.

Placement order
---------------
The number printed beside each part is the order a person builds the layout in:

1. static parts (supports, tracks, walls, containers, a lever's axle): they hold the rest;
2. parts hinged on them (a lever's plank goes on its axle);
3. the other moving parts (planks, dominoes, a ball), which rest on what is already there;
4. last, the moving parts the chain starts with (the bodies of the root event: the leaning
   first domino, the ball that rolls first), so nothing sets the chain off early.

Within each tier the lowest part comes first (its lowest point, world Z, to the millimetre),
so a part standing on another one is placed after it; ties keep the scenario's file order
(a domino run stays in its order).

Tolerances
----------
A layout file (JSON or TOML) may carry placement tolerances in real units, as the optimiser
writes them::

    "tolerances": {"top_track.x": [0.002, 0.004], "goblet.roll": [1.5, 1.5]}

``[down, up]`` (metres or degrees; signs are ignored; one number means symmetric) is how far
below and above its value the parameter may be placed. They are printed beside the part as
``x ± 3 mm`` or ``x -2/+4 mm`` (``roll ± 2°`` for angles). A parameter belongs to an object;
the parameters of a frame (a ``part = "frame"`` object such as ``bottom_track_joint`` or a
domino run) are printed, with the frame's name, beside every part placed through that frame
(its descendants in the ``parent`` chain).

The library modules are imported inside the commands, so the CLI starts fast.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from rgmcad.errors import RgmcadError, ScenarioError, UsageError

PAPER_CHOICES = ("a4", "letter", "a3", "auto")
PLANE_CHOICES = ("floor", "board", "xy", "xz", "yz")
DEFAULT_PAPER = "a4"
DEFAULT_OVERLAP_MM = 12.0


def _say(text: str = "") -> None:
    """One line on stdout (the library itself never prints)."""
    sys.stdout.write(text + "\n")


# --- tolerances -----------------------------------------------------------------------------------


def _number(v: float) -> str:
    s = f"{v:.1f}" if v >= 1.0 else f"{v:.2g}"
    return s.rstrip("0").rstrip(".") if "." in s else s


def format_tolerance(label: str, component: str, down: float, up: float) -> str:
    """``"x ± 3 mm"``, ``"x -2/+4 mm"`` or ``"roll ± 2°"`` from metres or degrees."""
    from rgmcad.geometry import ANGLE_KEYS

    angle = component in ANGLE_KEYS
    factor, unit = (1.0, "°") if angle else (1000.0, " mm")
    d, u = _number(down * factor), _number(up * factor)
    if d == u:
        return f"{label} ± {d}{unit}"
    return f"{label} -{d}/+{u}{unit}"


def part_tolerances(scenario, obj_name: str, tolerances) -> tuple[str, ...]:
    """Notes for the body of object ``obj_name``: its own parameters first (``x ± 3 mm``),
    then those of the frames it is placed through (``bottom_track_joint.roll ± 2°``)."""
    from rgmcad.geometry import POSE_KEYS
    from rgmcad.scene.scenario import FRAME

    notes = []
    chain = [obj_name]
    parent = scenario.objects[obj_name].parent
    while parent is not None:
        chain.append(parent)
        parent = scenario.objects[parent].parent
    for depth, name in enumerate(chain):
        if depth and scenario.objects[name].part != FRAME:
            continue
        for component in POSE_KEYS:
            key = f"{name}.{component}"
            if key in tolerances:
                label = component if depth == 0 else key
                notes.append(format_tolerance(label, component, *tolerances[key]))
    return tuple(notes)


# --- scene -> template inputs ---------------------------------------------------------------------


def placement_order(scenario, scene) -> list[str]:
    """Names of the scene's non-plane bodies in build order (see the module docstring)."""
    hinged = {h.moving for h in scene.hinges}
    trigger = set(scenario.events[scenario.root_event].objects.values())
    keys = {}
    for index, body in enumerate(scene.bodies.values()):
        if body.plane:
            continue
        tier = (0 if body.static else 1 if body.name in hinged
                else 3 if body.object in trigger else 2)
        lowest_mm = round(float(body.world_vertices()[:, 2].min()) * 1000.0)
        keys[body.name] = (tier, lowest_mm, index)
    return sorted(keys, key=keys.__getitem__)


def template_inputs(scenario, scene, tolerances=None):
    """``(parts, base_planes)`` for :func:`rgmcad.printing.template.make_template` from a scene."""
    import numpy as np

    from rgmcad.printing.template import BasePlane, PlacedPart

    tolerances = tolerances or {}
    order = {name: k + 1 for k, name in enumerate(placement_order(scenario, scene))}
    parts, planes = [], []
    for body in scene.bodies.values():
        pose = np.asarray(body.pose, float)
        if body.plane:
            planes.append(BasePlane(body.name, pose[:3, 3].copy(), pose[:3, 2].copy()))
            continue
        parts.append(PlacedPart(body.name, order[body.name], body.world_vertices(),
                                np.asarray(body.built.faces), pose,
                                part_tolerances(scenario, body.object, tolerances)))
    parts.sort(key=lambda p: p.order)
    return parts, planes


# --- commands -------------------------------------------------------------------------------------


def cmd_template(args) -> int:
    from rgmcad.cli.common import load_parts_of, load_scenario_arg
    from rgmcad.printing.template import make_template
    from rgmcad.scene.bodies import make_scene
    from rgmcad.scene.layout_files import read_tolerances, resolve_layout

    t0 = time.perf_counter()
    scenario = load_scenario_arg(args)
    name, values = resolve_layout(scenario, args.layout, None)
    tolerances = {}
    if args.layout and args.layout not in scenario.layouts:  # a layout file
        tolerances = read_tolerances(scenario, Path(args.layout))
    scene = make_scene(scenario, values, load_parts_of(scenario, args))
    parts, planes = template_inputs(scenario, scene, tolerances)
    paper = None if args.paper == "auto" else args.paper
    try:
        result = make_template(parts, planes, Path(args.out), plane=args.plane, paper=paper,
                               overlap_mm=args.overlap,
                               title=f"{scenario.name}, layout {name}")
    except RgmcadError:
        raise
    except ValueError as exc:  # no such plane in the scenario, overlap out of range, too big
        raise ScenarioError(str(scenario.path), "template", str(exc)) from None
    except OSError as exc:
        raise UsageError(str(args.out), "--out", f"cannot write the template ({exc})") \
            from None
    wall = time.perf_counter() - t0
    cols, rows = result.grid
    if args.json:
        _say(json.dumps({
            "scenario": scenario.name, "layout": name,
            "pdf": str(result.pdf), "svg": str(result.svg),
            "plane": result.plane, "paper": result.paper, "orientation": result.orientation,
            "grid": [cols, rows], "sheets": list(result.sheet_labels), "pages": result.n_pages,
            "overlap_mm": result.overlap_mm,
            "parts": [{"name": p.name, "order": p.order,
                       "centroid_world": [float(v) for v in p.centroid_world],
                       "tolerances": list(p.tolerances)} for p in result.parts],
            "wall_time": wall,
        }))
        return 0
    base = f" ({result.frame.base})" if result.frame.base not in ("", result.plane) else ""
    _say(f"{scenario.name}, layout {name}: {len(result.parts)} parts drawn on the "
         f"{result.plane} plane{base}")
    _say(f"{result.paper} {result.orientation}: {cols} x {rows} sheets "
         f"({', '.join(result.sheet_labels)}) and the assembly map, {result.n_pages} pages, "
         f"{result.overlap_mm:g} mm overlap")
    if tolerances:
        _say(f"tolerances from {args.layout}: {len(tolerances)} parameters")
    _say(f"  {result.pdf}")
    _say(f"  {result.svg}  (1:1, millimetres)")
    _say("print at 100 % / actual size; check a printed sheet with: "
         "rgmcad verify-print PHOTO.jpg")
    _say(f"done in {wall:.1f} s")
    return 0


def cmd_verify_print(args) -> int:
    from rgmcad.printing.check import verify_print

    check = verify_print(Path(args.image))
    if args.json:
        _say(json.dumps({
            "image": check.path, "sheet": check.sheet, "paper": check.paper,
            "tag_ids": list(check.tag_ids), "scale": check.scale,
            "scale_error_percent": check.scale_error_percent,
            "scale_xy": list(check.scale_xy), "method": check.method,
            "residual_mm": check.residual_mm, "ok": _ok(check), "message": check.message,
        }))
        return 0
    paper = f", {check.paper}" if check.paper else ""
    _say(f"sheet {check.sheet}{paper} ({len(check.tag_ids)} marks, measured by "
         f"{'the scan resolution' if check.method == 'dpi' else 'the sheet edges'})")
    _say(check.message)
    return 0


def _ok(check) -> bool:
    from rgmcad.printing.check import TOLERANCE_PERCENT

    return abs(check.scale_error_percent) <= TOLERANCE_PERCENT


# --- argparse -------------------------------------------------------------------------------------


def configure_template(p) -> None:
    p.add_argument("scenario", help="scenario file (TOML), e.g. scenarios/ballrun.toml")
    p.add_argument("--layout", help="a named layout of the scenario (default: initial) or a "
                   "layout file (JSON/TOML with `values` or `vector`, and optional "
                   "`tolerances`)")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for template.pdf and template.svg (created if missing)")
    p.add_argument("--plane", choices=PLANE_CHOICES, default=None,
                   help="plane to draw on: the scenario's horizontal (floor) or vertical "
                   "(board) base plane, or an axis plane; default: the one the parts stand on")
    p.add_argument("--paper", choices=PAPER_CHOICES, default=DEFAULT_PAPER,
                   help=f"paper size (default: {DEFAULT_PAPER}); auto picks the size needing "
                   "the fewest sheets, A3 included; orientation is always chosen for the "
                   "fewest sheets")
    p.add_argument("--overlap", type=float, default=DEFAULT_OVERLAP_MM, metavar="MM",
                   help=f"width of the strips neighbouring sheets share, mm "
                   f"(default: {DEFAULT_OVERLAP_MM:g})")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def configure_verify_print(p) -> None:
    p.add_argument("image", help="a scan (with its dpi recorded) or a photo of one printed "
                   "sheet, the whole sheet in view on a darker background")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")

