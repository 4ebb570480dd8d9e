"""The ``rgmcad`` command line: a thin layer over the library.

Commands come from one table (:data:`COMMANDS`). Bad input (a file, a key, a value) prints one
line naming the file, the key and what is allowed, and exits with status 2.
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rgmcad.errors import ScenarioError
from rgmcad.shipped import shipped_dir

SCENARIO_DIR = shipped_dir("scenarios")


# --- shared helpers ---------------------------------------------------------------------------


def _load(args):
    from rgmcad.scene.scenario import load_scenario

    return load_scenario(args.scenario)


def _parts(scenario, args):
    from rgmcad.scene.bodies import load_parts

    first = not Path(args.build_dir).exists()
    if first:
        print(f"building parts into {args.build_dir} (first run only)...", file=sys.stderr)
    return load_parts(scenario, Path(args.build_dir))


def resolve_layout(scenario, layout: str | None, vector: str | None):
    """(name, real values (d,)) of ``--layout NAME|FILE`` or ``--vector v1,...,vd``."""
    from rgmcad.scene.design_space import values_from_mapping, values_from_vector

    where = str(scenario.path)
    if vector is not None:
        try:
            v = np.array([float(x) for x in vector.split(",")], float)
        except ValueError:
            raise ScenarioError("--vector", "", "expected comma-separated numbers") from None
        if v.shape != (scenario.dimension,):
            raise ScenarioError("--vector", "", f"expected {scenario.dimension} values "
                                f"(the design space of {scenario.name}), got {len(v)}")
        if np.any(v < 0) or np.any(v > 1):
            raise ScenarioError("--vector", "", "values must lie in [0, 1]")
        return "vector", values_from_vector(scenario, v)
    name = layout or "initial"
    if name in scenario.layouts:
        return name, values_from_mapping(scenario, scenario.layouts[name])
    path = Path(name)
    if not path.exists():
        raise ScenarioError(where, "layouts", f"unknown layout {name!r}: not a layout of this "
                            f"scenario ({', '.join(scenario.layouts)}) nor a file")
    return path.stem, load_layout_file(scenario, path)


def load_layout_file(scenario, path: Path) -> np.ndarray:
    """Real values (d,) from a layout file (JSON or TOML) with ``values`` or ``vector``."""
    import tomllib

    from rgmcad.scene.design_space import values_from_mapping, values_from_vector

    try:
        text = path.read_text()
        data = tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (OSError, ValueError) as exc:
        raise ScenarioError(str(path), "", f"cannot read the layout file ({exc})") from None
    if not isinstance(data, dict):
        raise ScenarioError(str(path), "", "a layout file holds a table")
    if data.get("scenario") not in (None, scenario.name):
        raise ScenarioError(str(path), "scenario", f"this layout is for {data['scenario']!r}, "
                            f"not {scenario.name!r}")
    if "values" in data:
        values = data["values"]
        if not isinstance(values, dict):
            raise ScenarioError(str(path), "values", "expected a table of parameter: value")
        names = {f.name for f in scenario.free}
        for k, v in values.items():
            if k not in names:
                raise ScenarioError(str(path), f"values.{k}", "not a free parameter; allowed: "
                                    + ", ".join(sorted(names)))
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise ScenarioError(str(path), f"values.{k}", "expected a number")
        return values_from_mapping(scenario, values)
    if "vector" in data:
        v = data["vector"]
        if not isinstance(v, list) or len(v) != scenario.dimension:
            raise ScenarioError(str(path), "vector", f"expected {scenario.dimension} numbers")
        return values_from_vector(scenario, np.asarray(v, float))
    raise ScenarioError(str(path), "", "a layout file needs `values` or `vector`")


def _print_table(rows: list[tuple], headers: tuple) -> None:
    widths = [max(len(str(x)) for x in col) for col in zip(headers, *rows, strict=False)]
    for row in (headers, *rows):
        print("  ".join(str(x).ljust(w) for x, w in zip(row, widths, strict=False)).rstrip())


# --- commands ---------------------------------------------------------------------------------


def cmd_simulate(args) -> int:
    from rgmcad.sim.run import simulate

    scenario = _load(args)
    name, values = resolve_layout(scenario, args.layout, args.vector)
    parts = _parts(scenario, args)
    observer, frames, fps = None, [], 30.0
    every = max(1, int(round(1 / (fps * scenario.settings.timestep))))
    if args.video:
        from rgmcad.sim.render import Renderer

        renderer = []

        def observer(world, t):
            if not renderer:
                renderer.append(Renderer(world, args.width, args.height))
            frames.append(renderer[0].image())

    result = simulate(scenario, values, parts, observer=observer, observe_every=every)
    if args.video and frames:
        from rgmcad.sim.render import save_video

        save_video(frames, Path(args.video), fps)
    if args.json:
        from rgmcad.scene.design_space import vector_from_values

        out = result.to_dict()
        out.update(scenario=scenario.name, layout=name,
                   vector=vector_from_values(scenario, values).tolist(),
                   values={f.name: float(v) for f, v in zip(scenario.free, values, strict=True)})
        if args.video:
            out["video"] = args.video
        print(json.dumps(out))
        return 0
    print(f"{scenario.name}, layout {name}")
    if result.outcome.value == "invalid":
        for o in result.validity.overlaps:
            print(f"  {o.first} and {o.second} overlap by {o.depth * 1000:.2f} mm")
    else:
        rows = [(e.name, e.state, "" if e.time is None else f"{e.time:.3f}")
                for e in sorted(result.events, key=lambda e: (e.time is None, e.time or 0))]
        _print_table(rows, ("event", "state", "time (s)"))
    print(f"outcome: {result.outcome.value} ({result.n_success}/{len(result.events)} events, "
          f"{result.sim_time:.3f} s simulated in {result.wall_time:.2f} s)")
    if args.video:
        print(f"video: {args.video}")
    return 0


def cmd_check(args) -> int:
    from rgmcad.scene.bodies import make_scene
    from rgmcad.sim.validity import check_validity

    scenario = _load(args)
    print(f"{scenario.name}: {scenario.description}")
    bodies = scenario.body_objects()
    print(f"\nobjects ({len(bodies)} parts, {len(scenario.runs)} domino runs):")
    rows = []
    for obj in scenario.objects.values():
        if obj.run is not None:
            continue
        if obj.name in scenario.runs:
            n = len(scenario.runs[obj.name])
            rows.append((obj.name, f"domino run ({n})", obj.parent or "-", ""))
            continue
        phys = obj.physical
        kind = ("frame" if obj.part == "frame" else "static" if phys.static
                else f"{phys.mass * 1000:.3g} g" if phys.mass is not None
                else f"{phys.density:g} kg/m3")
        rows.append((obj.name, obj.part, obj.parent or "-", kind))
    _print_table(rows, ("name", "part", "parent", "mass"))
    print(f"\nfree parameters (d = {scenario.dimension}):")
    _print_table([(i, f.name, f"[{f.low:g}, {f.high:g}]", f.unit)
                  for i, f in enumerate(scenario.free)], ("#", "parameter", "range", "unit"))
    print(f"\nevents ({len(scenario.events)}):")
    _print_table([_event_row(n, e, scenario.settings.event_timeout)
                  for n, e in scenario.events.items()],
                 ("event", "type", "objects", "after", "join", "negate", "hold (s)",
                  "timeout (s)"))
    parts = _parts(scenario, args)
    print("\nlayouts:")
    from rgmcad.scene.design_space import values_from_mapping, vector_from_values

    for name, mapping in scenario.layouts.items():
        values = values_from_mapping(scenario, mapping)
        vec = vector_from_values(scenario, values)
        validity = check_validity(make_scene(scenario, values, parts))
        inside = "inside" if np.all((vec >= 0) & (vec <= 1)) else "OUTSIDE"
        status = "valid" if validity.valid else "invalid: " + "; ".join(
            f"{o.first}/{o.second} overlap {o.depth * 1000:.2f} mm" for o in validity.overlaps)
        print(f"  {name}: {status}; {inside} the design space")
    return 0


def _event_row(name, event, default_timeout: float) -> tuple:
    """One row of ``check``'s event table: what the event watches, when, and how."""
    objects = ", ".join(event.objects.values())
    if event.end is not None:
        objects += f" (end {event.end})"
    elif event.point is not None:
        objects += " (point {:g}, {:g}, {:g})".format(*event.point)
    timeout = (f"{event.timeout:g}" if event.timeout is not None
               else f"{default_timeout:g} (default)")  # [simulation] event_timeout
    return (name, event.type, objects,
            (" & " if event.join == "all" else " | ").join(event.after) or "(root)",
            event.join if event.after else "-", event.negate.label, f"{event.hold:g}", timeout)


def cmd_render(args) -> int:
    from rgmcad.scene.bodies import make_scene
    from rgmcad.sim.render import Renderer, save_png
    from rgmcad.sim.world import World

    scenario = _load(args)
    name, values = resolve_layout(scenario, args.layout, args.vector)
    parts = _parts(scenario, args)
    world = World(make_scene(scenario, values, parts), scenario.settings)
    save_png(Renderer(world, args.width, args.height).image(), Path(args.out))
    print(f"{args.out}: {scenario.name}, layout {name}")
    return 0


def cmd_build_parts(args) -> int:
    from tqdm import tqdm

    from rgmcad.parts.build import build_parts, write_manifest
    from rgmcad.scene.scenario import load_scenario

    paths = [Path(p) for p in args.scenarios] or sorted(SCENARIO_DIR.glob("*.toml"))
    scenarios = [load_scenario(p) for p in paths]
    instances = [(s.family(o), o.params) for s in scenarios for o in s.body_objects()]
    out = Path(args.out)
    bar = tqdm(total=None, unit="part", desc="building parts", file=sys.stderr)
    counts = {"built": 0, "cached": 0}

    def progress(done, total, pid, cached):
        bar.total = total
        counts["cached" if cached else "built"] += 1
        bar.set_postfix_str(pid)
        bar.update(1)

    t0 = time.perf_counter()
    parts = build_parts(instances, out, progress=progress, force=args.force)
    bar.close()
    by_id = {p.id: p for p in parts}
    from rgmcad.parts.build import part_id

    objects = {}
    for s in scenarios:
        for o in s.body_objects():
            pid = part_id(s.family(o), o.params)
            main = by_id[pid].bodies.get("")
            entry = {"part": pid}
            if main is not None and not o.physical.static:
                mass = o.physical.mass or o.physical.density * main.volume
                entry.update(mass=mass, inertia=(main.inertia_unit * mass / main.volume).tolist())
            objects[f"{s.name}/{o.name}"] = entry
    write_manifest(parts, out, extra={"objects": objects})
    print(f"{len(parts)} parts ({counts['built']} built, {counts['cached']} cached) in "
          f"{time.perf_counter() - t0:.1f} s: {out}/manifest.json")
    return 0


# --- parser -----------------------------------------------------------------------------------


def _layout_args(p: argparse.ArgumentParser) -> None:
    group = p.add_mutually_exclusive_group()
    group.add_argument("--layout", help="a named layout of the scenario (default: initial) or a "
                       "layout file (JSON/TOML with `values` or `vector`)")
    group.add_argument("--vector", help="a design vector v1,...,vd in [0, 1]")


def _scenario_arg(p):
    p.add_argument("scenario", help="scenario file (TOML), e.g. scenarios/simple.toml")


def _configure_simulate(p):
    _scenario_arg(p)
    _layout_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--video", metavar="FILE", help="write a video of the run (.mp4 or .gif)")
    p.add_argument("--width", type=int, default=640)
    p.add_argument("--height", type=int, default=480)


def _configure_check(p):
    _scenario_arg(p)


def _configure_render(p):
    _scenario_arg(p)
    _layout_args(p)
    p.add_argument("--out", required=True, metavar="FILE.png")
    p.add_argument("--width", type=int, default=1024)
    p.add_argument("--height", type=int, default=768)


def _configure_build_parts(p):
    p.add_argument("scenarios", nargs="*", help="scenario files (default: every shipped one)")
    p.add_argument("--out", default=None, help="output folder (default: the build folder)")
    p.add_argument("--force", action="store_true", help="rebuild parts already built")


def _lazy(module: str, name: str) -> Callable:
    """``rgmcad.<module>.<name>``, imported on first call (keeps the CLI's start-up light)."""

    def call(*args):
        import importlib

        return getattr(importlib.import_module(f"rgmcad.{module}"), name)(*args)

    return call


COMMANDS: dict[str, tuple[Callable, Callable, str]] = {
    "simulate": (_configure_simulate, cmd_simulate,
                 "simulate one layout and print the event timeline"),
    "check": (_configure_check, cmd_check,
              "validate a scenario file and summarise it"),
    "render": (_configure_render, cmd_render, "draw a layout to a PNG"),
    "build parts": (_configure_build_parts, cmd_build_parts,
                    "build the parts of the shipped scenarios (STEP, STL, GLB, collision pieces)"),
    "template": (_lazy("cli.printing", "configure_template"), _lazy("cli.printing", "cmd_template"),
                 "write a printable 1:1 tiled assembly template (PDF and SVG) of a layout"),
    "verify-print": (_lazy("cli.printing", "configure_verify_print"),
                     _lazy("cli.printing", "cmd_verify_print"),
                     "measure the scale a template sheet was printed at, from a scan or photo"),
    "optimize": (_lazy("cli.optimize", "configure_optimize"),
                 _lazy("cli.optimize", "cmd_optimize"),
                 "learn the success probability and optimise a robust layout (resumable run)"),
    "evaluate": (_lazy("cli.optimize", "configure_evaluate"),
                 _lazy("cli.optimize", "cmd_evaluate"),
                 "measure a layout's local and global robustness by simulation"),
}


def build_parser() -> argparse.ArgumentParser:
    from rgmcad.parts.build import DEFAULT_BUILD_DIR

    parser = argparse.ArgumentParser(prog="rgmcad", description="Design chain-reaction "
                                     "contraptions that work when built by hand.")
    parser.add_argument("--build-dir", default=str(DEFAULT_BUILD_DIR),
                        help=f"where built parts are cached (default: {DEFAULT_BUILD_DIR})")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    groups: dict[str, argparse._SubParsersAction] = {}
    for name, (configure, run, help_text) in COMMANDS.items():
        words = name.split()
        if len(words) == 1:
            p = sub.add_parser(name, help=help_text, description=help_text)
        else:  # multi-word commands: "build parts"
            if words[0] not in groups:
                g = sub.add_parser(words[0], help=f"{words[0]} ...")
                groups[words[0]] = g.add_subparsers(dest="subcommand", required=True,
                                                    metavar="WHAT")
            p = groups[words[0]].add_parser(words[1], help=help_text, description=help_text)
        configure(p)
        p.set_defaults(run=run)
    return parser


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s")
    args = build_parser().parse_args(argv)
    if getattr(args, "out", 0) is None:
        args.out = args.build_dir
    try:
        return args.run(args)
    except ScenarioError as exc:
        print(f"rgmcad: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rgmcad: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
