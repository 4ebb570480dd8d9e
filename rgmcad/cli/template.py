"""``rgmcad template``: a printable 1:1 tiled assembly template of a layout.

``rgmcad template SCENARIO --layout NAME|FILE --out DIR`` poses a layout and writes
``DIR/template.pdf`` (tiled, tagged sheets) and ``DIR/template.svg`` (1:1, millimetres) with
:func:`rgmcad.printing.template.scene_template`; placement order and tolerance notes are
described in :mod:`rgmcad.printing.inputs`.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

from rgmcad.cli.common import (
    add_layout_args,
    add_scenario_arg,
    layout_arg,
    load_parts_of,
    load_scenario_arg,
    say,
)
from rgmcad.cli.paths import finite, output_dir
from rgmcad.errors import UsageError

PAPER_CHOICES = ("a4", "letter", "a3", "auto")
PLANE_CHOICES = ("floor", "board", "xy", "xz", "yz")
DEFAULT_PAPER = "a4"
DEFAULT_OVERLAP_MM = 12.0


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p, vector=False)
    p.epilog = ("A layout file may also carry `tolerances` (as the optimiser writes them); "
                "they are printed beside the parts.")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder for template.pdf and template.svg (created if missing)")
    p.add_argument("--plane", choices=PLANE_CHOICES, default=None,
                   help="plane to draw on: the scenario's horizontal (floor) or vertical "
                   "(board) base plane, or an axis plane; default: the one the parts stand on")
    p.add_argument("--paper", choices=PAPER_CHOICES, default=DEFAULT_PAPER,
                   help=f"paper size (default: {DEFAULT_PAPER}); auto picks the size needing "
                   "the fewest sheets, A3 included; orientation is always chosen for the "
                   "fewest sheets")
    p.add_argument("--overlap", type=finite, default=DEFAULT_OVERLAP_MM, metavar="MM",
                   help=f"width of the strips neighbouring sheets share, mm "
                   f"(default: {DEFAULT_OVERLAP_MM:g})")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--bom-json", action="store_true", help="print the bill of materials and "
                   "the assembly steps as one JSON object on stdout instead")


def run(args) -> int:
    from rgmcad.printing.template import layout_notes, scene_template
    from rgmcad.scene.bodies import make_scene

    t0 = time.perf_counter()
    output_dir(args.out, "--out", files=("template.pdf", "template.svg"))
    scenario = load_scenario_arg(args)
    name, values = layout_arg(scenario, args)
    notes = layout_notes(scenario, args.scenario, args.layout, values, by_value=bool(args.value))
    tolerances, note = notes.tolerances, notes.note
    scene = make_scene(scenario, values, load_parts_of(scenario, args))
    paper = None if args.paper == "auto" else args.paper
    try:
        result = scene_template(scenario, scene, Path(args.out), tolerances=tolerances,
                                plane=args.plane, paper=paper, overlap_mm=args.overlap,
                                title=f"{scenario.name}, layout {name}", note=note,
                                push=notes.push, ball_mass=notes.ball_mass)
    except OSError as exc:
        raise UsageError(str(args.out), "--out", f"cannot write the template ({exc})") \
            from None
    wall = time.perf_counter() - t0
    cols, rows = result.grid
    if args.bom_json:
        say(json.dumps({"layout": name, **result.making.to_json()}))
        return 0
    if args.json:
        say(json.dumps({
            "scenario": scenario.name, "layout": name,
            "pdf": str(result.pdf), "svg": str(result.svg),
            "plane": result.plane, "paper": result.paper, "orientation": result.orientation,
            "grid": [cols, rows], "sheets": list(result.sheet_labels), "pages": result.n_pages,
            "empty_sheets": list(result.empty_sheets), "built_by_hand": note or None,
            "overlap_mm": result.overlap_mm,
            "parts": [{"name": p.name, "order": p.order,
                       "centroid_world": [float(v) for v in p.centroid_world],
                       "tolerances": _own(tolerances, p.name), "notes": list(p.tolerances)}
                      for p in result.parts],
            "frames": [{"name": f.name, "tolerances": _own(tolerances, f.name),
                        "notes": list(f.notes[1:])} for f in result.frames],
            "ropes": [{"name": r.name, "length": r.rope.length, "path_length": r.rope.path_length,
                       "path_world": r.rope.points.tolist()} for r in result.ropes],
            "wall_time": wall,
        }))
        return 0
    base = f" ({result.frame.base})" if result.frame.base not in ("", result.plane) else ""
    say(f"{scenario.name}, layout {name}: {len(result.parts)} parts drawn on the "
        f"{result.plane} plane{base}")
    say(f"{result.paper} {result.orientation}: {cols} x {rows} sheets "
        f"({', '.join(result.sheet_labels)}) and the assembly map, {result.n_pages} pages, "
        f"{result.overlap_mm:g} mm overlap")
    if result.empty_sheets:
        n = len(result.empty_sheets)
        say(f"{n} of {cols * rows} sheets hold nothing to place ({', '.join(result.empty_sheets)}):"
            " they only hold their neighbours in line, and say so")
    if tolerances:
        say(f"tolerances from {args.layout}: {len(tolerances)} parameters")
    if note:
        say(f"on the cover: {note}")
    say(f"  {result.pdf}")
    say(f"  {result.svg}  (1:1, millimetres)")
    say("print at 100 % / actual size; check a printed sheet with: "
        "rgmcad verify-print PHOTO.jpg")
    say(f"done in {wall:.1f} s")
    return 0


def _own(tolerances, name: str) -> dict:
    """The layout file's tolerances of object ``name``'s parameters: ``{parameter: [down,
    up]}`` in metres and degrees, as the file gives them."""
    return {key: [float(v) for v in value] for key, value in tolerances.items()
            if key.partition(".")[0] == name}
