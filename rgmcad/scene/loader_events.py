"""The ``[events]`` table of a scenario file: the causal graph, read into EventSpecs.

Each event names its type (:data:`~rgmcad.scene.eventspec.EVENT_TYPES`), the bodies in its
roles, its parameters, its parents (``after``) and how it resolves (join, negate, hold,
timeout, the point of the body whose motion counts); the graph must be acyclic with one root.
"""

from __future__ import annotations

import networkx as nx

from rgmcad.errors import ScenarioError
from rgmcad.parts.family import MAIN
from rgmcad.scene.eventspec import ENDS, EVENT_TYPES, NEGATE_VALUES, POINT_KEYS, Negation
from rgmcad.scene.loader_checks import check_keys, check_name, expect, key_text
from rgmcad.scene.model import FRAME, EventSpec, SimulationSettings, body_key
from rgmcad.scene.schema import EVENT, EVENT_PARAMS, MAX_EVENTS, POINT, show

EVENT_COMMON_KEYS = ("type", "after", "join", "negate", "hold", "timeout", "description")
EVENT_POINT_KEYS = ("point", "end")  # events whose type takes_point


def _resolve_body(ref, objects, families, runs, where, key) -> str:
    """Canonical body name for an event argument; accepts ``run[-1]`` for a run's last domino."""
    if not isinstance(ref, str):
        raise ScenarioError(where, key, f"expected an object name, got {show(ref)}")
    if "[" in ref and ref.endswith("]"):
        run, _, index = ref[:-1].partition("[")
        if run in runs:
            try:
                i = int(index)
                return runs[run][i]
            except (ValueError, IndexError):
                raise ScenarioError(where, key, f"run {run!r} has {len(runs[run])} dominoes; "
                                    f"{show(ref)} is not one of them") from None
    obj_name, _, sub = ref.partition(".")
    obj = objects.get(obj_name)
    if obj is not None and obj.part != FRAME:
        if not sub:
            return ref
        if sub in families[obj.part].fixed_bodies(obj.params):
            return ref
    raise ScenarioError(where, key, f"unknown object {show(ref)}; events name bodies "
                        "(objects that are parts, run[i] dominoes, or object.axle)")


def parse_events(raw, objects, families, runs, where,
                 settings: SimulationSettings | None = None) -> dict[str, EventSpec]:
    """The ``[events]`` table ``raw`` read into ``{name: EventSpec}``, in file order.

    ``objects`` and ``runs`` are the scenario's, already read (events name their bodies);
    ``settings`` give the default timeout that ``hold`` must fit in.
    """
    raw = expect(raw, dict, where, "events")
    if len(raw) > MAX_EVENTS:
        raise ScenarioError(where, "events", f"{len(raw):,} events; at most {MAX_EVENTS:,}")
    settings = settings or SimulationSettings()
    events = {}
    for name, ev in raw.items():
        key = f"events.{key_text(name)}"
        check_name(name, where, key)
        ev = expect(ev, dict, where, key)
        etype = ev.get("type")
        if not isinstance(etype, str) or etype not in EVENT_TYPES:
            raise ScenarioError(where, f"{key}.type", f"unknown event type {show(etype)}; "
                                f"allowed: {', '.join(EVENT_TYPES)}")
        spec = EVENT_TYPES[etype]
        extra = EVENT_POINT_KEYS if spec.takes_point else ()
        for k in EVENT_POINT_KEYS:
            if k in ev and not spec.takes_point:
                takers = ", ".join(t.name for t in EVENT_TYPES.values() if t.takes_point)
                raise ScenarioError(where, f"{key}.{k}", f"a {etype} event takes no point or "
                                    f"end (only {takers} do)")
        check_keys(ev, (*EVENT_COMMON_KEYS, *spec.roles, *spec.params, *extra), where, key)
        roles = {}
        for role in spec.roles:
            if role not in ev:
                raise ScenarioError(where, f"{key}.{role}", f"a {etype} event needs {role!r}")
            roles[role] = _resolve_body(ev[role], objects, families, runs, where, f"{key}.{role}")
        params = {}
        for p, default in spec.params.items():
            if p in ev:
                params[p] = EVENT_PARAMS[p].read(ev[p], where, f"{key}.{p}")
            elif default is None:
                raise ScenarioError(where, f"{key}.{p}", f"a {etype} event needs {p!r}")
            else:
                params[p] = default
        after = expect(ev.get("after", []), list, where, f"{key}.after")
        for i, parent in enumerate(after):
            expect(parent, str, where, f"{key}.after[{i}]")
        join = ev.get("join", "all")
        if join not in ("all", "any"):
            raise ScenarioError(where, f"{key}.join",
                                f"unknown join {show(join)}; allowed: all, any")
        if join == "any" and len(set(after)) < 2:
            raise ScenarioError(where, f"{key}.join", "join = \"any\" waits for the first of two "
                                "or more events in `after`; this event has "
                                f"{len(set(after)) or 'none'}: write join = \"all\" or name "
                                "the alternatives")
        negate = _parse_negate(ev.get("negate", False), where, f"{key}.negate")
        timeout = ev.get("timeout")
        if timeout is not None:
            timeout = EVENT["timeout"].read(timeout, where, f"{key}.timeout")
        hold = _parse_hold(ev.get("hold", 0.0), timeout, settings, where, key)
        if negate is Negation.ALWAYS:
            _check_always_fits(timeout, settings, where, key)
        point, end = _parse_point(ev, roles, objects, families, where, key)
        events[name] = EventSpec(
            name=name, type=etype, objects=roles, params=params, after=tuple(after), join=join,
            negate=negate, hold=hold, timeout=timeout,
            description=expect(ev.get("description", ""), str, where, f"{key}.description"),
            point=point, end=end,
        )
    for name, ev in events.items():
        for parent in ev.after:
            if parent not in events:
                raise ScenarioError(where, f"events.{name}.after",
                                    f"unknown event {show(parent)}; allowed: {', '.join(events)}")
            if parent == name:
                raise ScenarioError(where, f"events.{name}.after", "an event cannot follow itself")
    if events:
        graph = nx.DiGraph()
        graph.add_nodes_from(events)
        graph.add_edges_from((p, n) for n, e in events.items() for p in e.after)
        if not nx.is_directed_acyclic_graph(graph):
            cycle = " -> ".join(e[0] for e in nx.find_cycle(graph))
            raise ScenarioError(where, "events", f"the causal graph has a cycle: {cycle}")
        roots = [n for n, e in events.items() if not e.after]
        if len(roots) != 1:
            raise ScenarioError(where, "events", "the causal graph needs exactly one root event "
                                f"(one without `after`); found {len(roots)}: {', '.join(roots)}")
    return events


def _parse_negate(value, where, key) -> Negation:
    if isinstance(value, bool):
        return Negation(value)
    if value == Negation.ALWAYS.value:
        return Negation.ALWAYS
    raise ScenarioError(where, key, f"expected {NEGATE_VALUES}, got {show(value)}")


def _parse_hold(value, timeout, settings, where, key) -> float:
    """``hold`` (s): at least 0 and shorter than the event's timeout, or it can never succeed."""
    hold = EVENT["hold"].read(value, where, f"{key}.hold")
    limit = timeout if timeout is not None else settings.event_timeout
    if not 0 <= hold < limit:
        source = ("its `timeout`" if timeout is not None
                  else "the scenario's [simulation] event_timeout")
        raise ScenarioError(where, f"{key}.hold", f"got {hold:g} s; allowed: 0 <= hold < "
                            f"{limit:g} s, the event's timeout ({source}): a longer hold "
                            "cannot be met before the event times out")
    return hold


def _check_always_fits(timeout, settings, where, key) -> None:
    """A ``negate = "always"`` event succeeds only at its timeout, so that must fit the run."""
    limit = timeout if timeout is not None else settings.event_timeout
    if limit >= settings.duration:
        name = "timeout" if timeout is not None else "negate"
        raise ScenarioError(where, f"{key}.{name}", f"a negate = \"always\" event succeeds at its "
                            f"timeout ({limit:g} s after it wakes), which must be shorter than "
                            f"the simulation's duration ({settings.duration:g} s)")


def _parse_point(ev, roles, objects, families, where, key):
    """(point, end) of an event: at most one given; ``point`` fills missing x, y, z with 0."""
    if "point" in ev and "end" in ev:
        raise ScenarioError(where, f"{key}.point", "give point or end, not both")
    if "end" in ev:
        end = ev["end"]
        if end not in ENDS:
            raise ScenarioError(where, f"{key}.end", f"unknown end {show(end)}; allowed: "
                                + ", ".join(f'"{e}"' for e in ENDS))
        for body in roles.values():
            obj_name, sub = body_key(body)
            obj = objects[obj_name]
            if sub == MAIN and families[obj.part].infinite:
                raise ScenarioError(where, f"{key}.end", f"{body!r} is an infinite plane: it "
                                    "has no ends; use point = { x = ..., y = ..., z = ... }")
        return None, end
    if "point" in ev:
        raw = ev["point"]
        what = "a table { x = ..., y = ..., z = ... } (metres, in the body's part frame)"
        if not isinstance(raw, dict):
            raise ScenarioError(where, f"{key}.point", f"expected {what}, got {show(raw)}")
        check_keys(raw, POINT_KEYS, where, f"{key}.point")
        return tuple(POINT[k].read(raw.get(k, 0.0), where, f"{key}.point.{k}")
                     for k in POINT_KEYS), None
    return None, None
