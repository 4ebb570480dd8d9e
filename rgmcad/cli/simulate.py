"""``rgmcad simulate``: simulate one layout, print its event timeline (or JSON), save a video.
Exit status 0 when the layout succeeds, 1 when it fails or is invalid (2: bad input)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

from rgmcad.cli.common import (
    add_layout_args,
    add_scenario_arg,
    layout_arg,
    load_parts_of,
    load_scenario_arg,
    print_table,
    say,
)
from rgmcad.cli.paths import finite, output_file, pixels
from rgmcad.cli.physics import add_physics_draw_args, physics_draw_arg

VIDEO_FPS = 30.0
VIDEO_SUFFIXES = (".mp4", ".gif")
MIN_PIXELS, MAX_PIXELS = 16, 4096
"""Range of a video frame's sides."""
MAX_VIDEO_BYTES = 2 * 2**30
"""Most memory the frames of a video may take (they are held until the video is written)."""


def configure(p) -> None:
    add_scenario_arg(p)
    add_layout_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--video", metavar="FILE", help="write a video of the run (.mp4 or .gif)")
    p.add_argument("--html", metavar="FILE", help="write a 3D replay of the run: one .html file "
                   "that plays in a browser, offline")
    size = pixels(MIN_PIXELS, MAX_PIXELS)
    p.add_argument("--width", type=size, default=640, help=f"video pixels, {MIN_PIXELS} to "
                   f"{MAX_PIXELS} (default 640)")
    p.add_argument("--height", type=size, default=480, help=f"video pixels, {MIN_PIXELS} to "
                   f"{MAX_PIXELS} (default 480)")
    p.add_argument("--speed", type=finite, default=0.25, help="video playback speed against "
                   "real time, 0.01 to 4 (default 0.25: a domino falls in a tenth of a second)")
    p.add_argument("--labels", action="store_true", help="write the parts' names in the video")
    p.add_argument("--until", type=finite, metavar="SECONDS", help="stop the run this many "
                   "seconds in, whatever is still moving (--json's final_poses: the bodies then)")
    add_physics_draw_args(p)


def run(args) -> int:
    from rgmcad.errors import UsageError
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.sim.render import record_video, video_frames
    from rgmcad.sim.run import Outcome, final_poses, simulate

    if args.video:
        output_file(args.video, "--video", VIDEO_SUFFIXES)
        if not 0.01 <= args.speed <= 4:
            raise UsageError("--speed", "", f"expected 0.01 to 4, got {args.speed:g}")
    if args.html:
        output_file(args.html, "--html", (".html", ".htm"))
    physics = physics_draw_arg(args)
    scenario = load_scenario_arg(args)
    if args.until is not None:
        scenario = _stopped_at(scenario, args.until)
    if args.video:
        frames = video_frames(scenario.settings, VIDEO_FPS, args.speed)
        need = frames * args.width * args.height * 3
        if need > MAX_VIDEO_BYTES:
            raise UsageError("--width/--height", "", f"{args.width} x {args.height} pixels for "
                             f"up to {frames} frames need {need / 2**30:.1f} GiB of memory, at "
                             f"most {MAX_VIDEO_BYTES >> 30} GiB allowed: expected a smaller video")
    name, values = layout_arg(scenario, args)
    parts = load_parts_of(scenario, args)
    if args.video:
        result = record_video(scenario, values, parts, Path(args.video), VIDEO_FPS,
                              args.width, args.height, args.speed, args.labels, physics)
    if args.html:
        from rgmcad.viewer.page import simulate_to_html

        result = simulate_to_html(scenario, values, parts, args.html,
                                  title=f"{scenario.name}, layout {name}", physics=physics)
    ends = {}  # body -> its pose when the run stopped, for --json
    if not (args.video or args.html):
        result = simulate(scenario, values, parts, physics=physics, **final_poses(ends))
    if args.json:
        out = result.to_dict()
        out.update(scenario=scenario.name, layout=name,
                   vector=vector_from_values(scenario, values).tolist(),
                   values={f.name: float(v) for f, v in zip(scenario.free, values, strict=True)})
        if ends:
            out["final_poses"] = ends
        out.update({k: v for k, v in (("video", args.video), ("html", args.html)) if v})
        if physics is not None:
            out["physics"] = {"ranges": physics.ranges.to_json(), "seed": physics.seed,
                              "draw": physics.index}
        say(json.dumps(out))
        return 0 if result.outcome is Outcome.SUCCESS else 1
    say(f"{scenario.name}, layout {name}" + ("" if physics is None else
        f", physical errors draw {physics.index} (seed {physics.seed}): "
        f"{physics.ranges.describe()}"))
    if result.outcome is Outcome.INVALID:
        shown, more = result.validity.shown()
        say("\n".join([f"  {o.first} by {o.depth * 1000:.2f} mm" if o.first.startswith("rope ")
                       else f"  {o.first} and {o.second} overlap by {o.depth * 1000:.2f} mm"
                       for o in shown] + [f"  {more}"] * bool(more)))
    else:
        rows = [(e.name, e.state, "" if e.time is None else f"{e.time:.3f}")
                for e in sorted(result.events, key=lambda e: (e.time is None, e.time or 0))]
        print_table(rows, ("event", "state", "time (s)"))
    spare = len(result.events) - result.n_success if result.outcome is Outcome.SUCCESS else 0
    say(f"outcome: {result.outcome.value} ({result.n_success}/{len(result.events)} events"
        + (f", the other {spare} not needed (alternatives)" if spare else "")
        + f", {result.sim_time:.3f} s simulated in {result.wall_time:.2f} s)"
        + ("" if args.until is None else f"; stopped at --until {args.until:g} s"))
    if args.video:
        say(f"video: {args.video}")
    if args.html:
        say(f"replay: {args.html}")
    return 0 if result.outcome is Outcome.SUCCESS else 1


def _stopped_at(scenario, seconds: float):
    """``scenario`` with its run cut ``seconds`` in (events still awake then fail)."""
    from rgmcad.errors import UsageError

    if not 0 < seconds <= scenario.settings.duration:
        raise UsageError("--until", f"{seconds:g}", "expected a time in (0, "
                         f"{scenario.settings.duration:g}] s, the scenario's [simulation] duration")
    return replace(scenario, settings=replace(scenario.settings, duration=seconds))
