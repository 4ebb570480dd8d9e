"""``rgmcad export``: a posed layout as one CAD assembly (:mod:`rgmcad.export`)."""

from __future__ import annotations

from pathlib import Path

from rgmcad.cli.common import (
    add_layout_args,
    add_scenario_arg,
    load_parts_of,
    load_scenario_arg,
    say,
    with_values,
)
from rgmcad.cli.paths import output_file
from rgmcad.cli.supports import read_supports

RUN_FILES = ("layout.step", "layout.glb")
"""What ``rgmcad optimize`` exports into its run directory."""


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p)
    p.add_argument("--out", required=True, metavar="FILE",
                   help="FILE.step (millimetres, each part named as in the scenario) or "
                   "FILE.glb (glTF binary, metres)")
    p.add_argument("--supports", metavar="FILE", help="add the stands of this supports.json "
                   "(`rgmcad supports`) to the assembly")


def export_files(args, layout: str | None, vector: str | None, outs: list[Path],
                 pairs=(), stands=()):
    """Pose ``--layout``/``--vector`` (with the ``--value`` ``pairs``) and write it to each of
    ``outs``; (layout name, number of parts)."""
    from rgmcad.export import export_layout
    from rgmcad.scene.bodies import make_scene
    from rgmcad.scene.layout_files import resolve_layout

    scenario = load_scenario_arg(args)
    name, values = with_values(scenario, *resolve_layout(scenario, layout, vector), pairs)
    scene = make_scene(scenario, values, load_parts_of(scenario, args))
    for out in outs:
        export_layout(scenario, scene, out, stands)
    return name, sum(not b.plane for b in scene.bodies.values())


def run(args) -> int:
    from rgmcad.export import EXPORT_SUFFIXES

    out = output_file(args.out, "--out", EXPORT_SUFFIXES)
    stands = read_supports(args.supports)
    name, n = export_files(args, args.layout, args.vector, [out], args.value, stands)
    extra = f" and {len(stands)} stands" if stands else ""
    say(f"{args.out}: {args.scenario_given}, layout {name}, {n} parts{extra}")
    return 0
