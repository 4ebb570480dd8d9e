"""``rgmcad render``: draw a layout to a PNG."""

from __future__ import annotations

from rgmcad.cli.common import (
    add_layout_args,
    add_scenario_arg,
    layout_arg,
    load_parts_of,
    load_scenario_arg,
    say,
)
from rgmcad.cli.paths import output_file, pixels

MAX_PIXELS = 8192
"""Largest picture side (8192 x 8192 takes about 3 GB and half a minute on the CPU)."""
MIN_PIXELS = 16


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p)
    p.add_argument("--out", required=True, metavar="FILE.png")
    p.add_argument("--width", type=pixels(MIN_PIXELS, MAX_PIXELS), default=1024,
                   help=f"pixels, {MIN_PIXELS} to {MAX_PIXELS} (default 1024)")
    p.add_argument("--height", type=pixels(MIN_PIXELS, MAX_PIXELS), default=768,
                   help=f"pixels, {MIN_PIXELS} to {MAX_PIXELS} (default 768)")
    p.add_argument("--labels", action="store_true", help="write each part's name beside it")
    p.add_argument("--no-scale-bar", dest="scale_bar", action="store_false",
                   help="leave out the scale bar (drawn at the depth of the layout's centre)")


def run(args) -> int:
    from rgmcad.scene.bodies import make_scene
    from rgmcad.sim.render import render_png

    out = output_file(args.out, "--out", (".png",))
    scenario = load_scenario_arg(args)
    name, values = layout_arg(scenario, args)
    scene = make_scene(scenario, values, load_parts_of(scenario, args))
    render_png(scenario, scene, out, args.width, args.height, show_labels=args.labels,
               show_scale=args.scale_bar)
    say(f"{args.out}: {scenario.name}, layout {name}")
    return 0
