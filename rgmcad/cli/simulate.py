"""``rgmcad simulate``: simulate one layout, print its event timeline (or JSON), save a video."""

from __future__ import annotations

import json
from pathlib import Path

from rgmcad.cli.common import (
    add_layout_args,
    add_scenario_arg,
    load_parts_of,
    load_scenario_arg,
    print_table,
    say,
)

VIDEO_FPS = 30.0


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--video", metavar="FILE", help="write a video of the run (.mp4 or .gif)")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)


def run(args) -> int:
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.layout_files import resolve_layout
    from rgmcad.sim.render import record_video
    from rgmcad.sim.run import Outcome, simulate

    scenario = load_scenario_arg(args)
    name, values = resolve_layout(scenario, args.layout, args.vector)
    parts = load_parts_of(scenario, args)
    if args.video:
        result = record_video(scenario, values, parts, Path(args.video), VIDEO_FPS,
                              args.width, args.height)
    else:
        result = simulate(scenario, values, parts)
    if args.json:
        out = result.to_dict()
        out.update(scenario=scenario.name, layout=name,
                   vector=vector_from_values(scenario, values).tolist(),
                   values={f.name: float(v) for f, v in zip(scenario.free, values, strict=True)})
        if args.video:
            out["video"] = args.video
        say(json.dumps(out))
        return 0
    say(f"{scenario.name}, layout {name}")
    if result.outcome is Outcome.INVALID:
        for o in result.validity.overlaps:
            say(f"  {o.first} and {o.second} overlap by {o.depth * 1000:.2f} mm")
    else:
        rows = [(e.name, e.state, "" if e.time is None else f"{e.time:.3f}")
                for e in sorted(result.events, key=lambda e: (e.time is None, e.time or 0))]
        print_table(rows, ("event", "state", "time (s)"))
    say(f"outcome: {result.outcome.value} ({result.n_success}/{len(result.events)} events, "
        f"{result.sim_time:.3f} s simulated in {result.wall_time:.2f} s)")
    if args.video:
        say(f"video: {args.video}")
    return 0
