"""``rgmcad supports``: stands for every raised static part of a layout, clear of the moving
bodies' paths (:mod:`rgmcad.making.clearance`), written as STL, STEP and card nets."""

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
from rgmcad.cli.paths import output_dir, whole_number
from rgmcad.errors import UsageError

SUPPORTS_FILE = "supports.json"


def read_supports(path: str | None) -> list:
    """The stands of ``--supports FILE`` (none without it); a bad file: one clear line."""
    if path is None:
        return []
    from rgmcad.making.stands import read_stands

    try:
        return read_stands(Path(path))
    except ValueError as exc:
        raise UsageError(path, "--supports", str(exc)) from None


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p, vector=False)
    p.add_argument("--out", required=True, metavar="DIR",
                   help=f"folder for S1.stl, S1.step, S1-card.svg, ... and {SUPPORTS_FILE}")
    p.add_argument("--runs", type=whole_number(0, 1000), default=50, metavar="N",
                   help="perturbed runs (a hand's 2 mm / 2 degree errors and physical errors) "
                   "the stands must stay clear of, besides the nominal run (default: 50)")
    p.add_argument("--seed", type=int, default=0, help="seed of those runs' draws (default: 0)")
    p.add_argument("--no-template", action="store_true", help="skip the template (the "
                   "layout's `rgmcad template` with the stands' footprints, in DIR/template)")
    p.add_argument("--no-step", action="store_true",
                   help="skip the STEP files (CadQuery; STL and card nets only)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args) -> int:
    from rgmcad.making.clearance import ClearanceSettings, plan_supports
    from rgmcad.making.stands import write_stand_files
    from rgmcad.scene.bodies import make_scene

    t0 = time.perf_counter()
    out = output_dir(args.out, "--out", files=(SUPPORTS_FILE,))
    scenario = load_scenario_arg(args)
    name, values = layout_arg(scenario, args)
    parts = load_parts_of(scenario, args)
    scene = make_scene(scenario, values, parts)
    plan = plan_supports(scenario, values, parts, ClearanceSettings(runs=args.runs, seed=args.seed))
    written = write_stand_files(plan.stands, out, step=not args.no_step)
    if not args.no_template:
        written += _template(scenario, args, name, values, scene, plan.stands, out / "template")
    document = {"scenario": scenario.name, "layout": name, "seed": args.seed, **plan.to_json()}
    (out / SUPPORTS_FILE).write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")
    if args.json:
        say(json.dumps({**document, "files": [str(p) for p in written],
                        "wall_time": time.perf_counter() - t0}))
        return 0
    say(f"{scenario.name}, layout {name}: {plan.summary()}")
    for stand in plan.stands:
        say(f"  {stand.describe()}")
    for part, why in plan.unsupported:
        say(f"  {part}: {why}")
    say(f"  {out / SUPPORTS_FILE} and {len(written)} files in {out}")
    say(f"done in {time.perf_counter() - t0:.1f} s")
    return 0 if not plan.unsupported else 1


def _template(scenario, args, name, values, scene, stands, folder) -> list:
    """The layout's template as `rgmcad template` makes it (tolerances, bill of materials,
    assembly steps), with the stands drawn, listed and placed in the steps."""
    from rgmcad.printing.template import layout_notes, scene_template

    notes = layout_notes(scenario, args.scenario, args.layout, values,
                         by_value=bool(getattr(args, "value", None)))
    result = scene_template(scenario, scene, folder, title=f"{scenario.name}, layout {name}",
                            tolerances=notes.tolerances, note=notes.note, push=notes.push,
                            ball_mass=notes.ball_mass, supports=stands)
    return [result.pdf, result.svg]
