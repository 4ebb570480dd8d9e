"""``rgmcad check``: validate a scenario file and summarise it. Exit status 1 when a named
layout is invalid (parts overlap) or outside the design space, naming the parameter and by
how much (2: a bad scenario file)."""

from __future__ import annotations

from rgmcad.cli.common import add_scenario_arg, load_parts_of, load_scenario_arg, print_table, say


def configure(p) -> None:
    add_scenario_arg(p)


def run(args) -> int:
    from rgmcad.errors import printable
    from rgmcad.scene.bodies import make_scene
    from rgmcad.scene.design_space import values_from_mapping
    from rgmcad.sim.validity import check_validity

    scenario = load_scenario_arg(args)
    # the description is free text from the file: its control characters are shown escaped
    # (names are checked when read: letters, digits, '_' and '-')
    say(f"{scenario.name}: {printable(scenario.description)}" if scenario.description
        else scenario.name)
    bodies = scenario.body_objects()
    n_runs = len(scenario.runs)
    say(f"\nobjects ({len(bodies)} parts, {n_runs} domino run{'' if n_runs == 1 else 's'}):")
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
    print_table(rows, ("name", "part", "parent", "mass"))
    if scenario.ropes:
        say(f"\nropes ({len(scenario.ropes)}):")
        print_table([(r.name, " -> ".join(
            [e.object or "world" for e in r.ends[:1]] + [f"{len(r.pulleys)} pulleys"] * bool(
                r.pulleys) + [e.object or "world" for e in r.ends[1:]]),
            f"{r.length:g} m" if r.length is not None else f"initial + {r.slack:g} m")
            for r in scenario.ropes.values()], ("rope", "path", "length"))
    say(f"\nfree parameters (d = {scenario.dimension}):")
    print_table([(i, f.name, f"[{f.low:g}, {f.high:g}]", f.unit)
                 for i, f in enumerate(scenario.free)], ("#", "parameter", "range", "unit"))
    say(f"\nevents ({len(scenario.events)}):")
    print_table([_event_row(n, e, scenario.settings.event_timeout)
                 for n, e in scenario.events.items()],
                ("event", "type", "objects", "after", "join", "negate", "hold (s)",
                 "timeout (s)"))
    parts = load_parts_of(scenario, args)
    say("\nlayouts:")
    bad = 0
    for name, mapping in scenario.layouts.items():
        values = values_from_mapping(scenario, mapping)
        validity = check_validity(make_scene(scenario, values, parts))
        shown, more = validity.shown()
        problems = [f"{o.first} by {o.depth * 1000:.2f} mm" if o.first.startswith("rope ")
                    else f"{o.first}/{o.second} overlap {o.depth * 1000:.2f} mm"
                    for o in shown] + [more] * bool(more) + _outside(scenario, values)
        bad += bool(problems)
        say(f"  {name}: " + ("valid, inside the design space" if not problems
                             else "INVALID: " + "; ".join(problems)))
    return 1 if bad else 0


def _outside(scenario, values) -> list[str]:
    """How far each parameter of ``values`` lies outside its range, in its unit."""
    from rgmcad.runs.report import user_scale

    out = []
    for f, v in zip(scenario.free, values, strict=True):
        k, unit = user_scale(f)
        if v < f.low or v > f.high:
            side, by = ("below", f.low - v) if v < f.low else ("above", v - f.high)
            out.append(f"{f.name} = {v * k:.6g} {unit} is {by * k:.3g} {unit} {side} its "
                       f"range [{f.low * k:g}, {f.high * k:g}] {unit}")
    return out


def _event_row(name, event, default_timeout: float) -> tuple:
    """One row of the event table: what the event watches, when, and how."""
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
