"""``rgmcad export``: a posed layout as one CAD assembly (:mod:`rgmcad.export`)."""

from __future__ import annotations

from rgmcad.cli.common import add_layout_args, add_scenario_arg, load_parts_of, load_scenario_arg, say
from rgmcad.cli.paths import output_file


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p)
    p.add_argument("--out", required=True, metavar="FILE",
                   help="FILE.step (millimetres, each part named as in the scenario) or "
                   "FILE.glb (glTF binary, metres)")


def run(args) -> int:
    from rgmcad.export import EXPORT_SUFFIXES, export_layout
    from rgmcad.scene.bodies import make_scene
    from rgmcad.scene.layout_files import resolve_layout

    out = output_file(args.out, "--out", EXPORT_SUFFIXES)
    scenario = load_scenario_arg(args)
    name, values = resolve_layout(scenario, args.layout, args.vector)
    scene = make_scene(scenario, values, load_parts_of(scenario, args))
    export_layout(scenario, scene, out)
    n = sum(not b.plane for b in scene.bodies.values())
    say(f"{args.out}: {scenario.name}, layout {name}, {n} parts")
    return 0
