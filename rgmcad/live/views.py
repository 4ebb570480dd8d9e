"""What the live page shows of a simulated layout, made from the viewer's own pieces: the run
recorded as a :class:`~rgmcad.viewer.recording.Replay`, a still one for a layout whose parts
overlap (those parts drawn red), two layouts side by side in one replay (one camera, one
clock), and the plain summary the page lists (outcome, events, overlaps with their depth).

Lengths are shown in millimetres and angles in degrees: :func:`display` and :func:`real`
convert, the same way for sliders and sweeps, so a value the page sends back is the value
the server simulated.
"""

from __future__ import annotations

from html import escape

import numpy as np

from rgmcad.geometry import transform_points, translation
from rgmcad.sim.causal import EventState
from rgmcad.sim.run import Outcome, SimulationResult
from rgmcad.viewer.page import html_page, replay_section
from rgmcad.viewer.recording import Replay, replay_payload, scene_meshes

__all__ = ["display", "real", "display_unit", "summary", "fails_at", "still_replay",
           "side_by_side", "viewer_html"]

_OVERLAP = (0.86, 0.12, 0.10)
_CLEAR_STATIC = (0.80, 0.80, 0.78)
_CLEAR_MOVING = (0.55, 0.62, 0.74)


def display_unit(unit: str) -> str:
    """The unit a free parameter is shown in: ``mm`` for metres, ``deg`` for degrees."""
    return "deg" if unit == "deg" else "mm"


def display(unit: str, value: float) -> float:
    """A real value (metres or degrees) as shown (millimetres or degrees)."""
    return float(value) if unit == "deg" else float(value) * 1000.0


def real(unit: str, value: float) -> float:
    """A shown value (millimetres or degrees) as the scenario's (metres or degrees)."""
    return float(value) if unit == "deg" else float(value) / 1000.0


def fails_at(result: SimulationResult) -> str | None:
    """The event a failed run fails at: the earliest one that failed, else the first one
    still awake when the run stopped; None for a success or an invalid layout."""
    if result.outcome is not Outcome.FAILURE:
        return None
    failed = [e for e in result.events if e.state is EventState.FAILURE]
    if failed:
        return min(failed, key=lambda e: e.time if e.time is not None else np.inf).name
    return next((e.name for e in result.events if e.state is EventState.AWAKE), None)


def summary(result: SimulationResult) -> dict:
    """The page's account of one simulation: outcome, the event it fails at, the events in
    the order they resolved (state, time), and the overlapping pairs with their depth (mm)."""
    events = sorted(result.events, key=lambda e: (e.time is None, e.time or 0.0))
    overlaps = [] if result.validity is None else [
        {"first": o.first, "second": o.second, "depth_mm": round(o.depth * 1000, 3)}
        for o in result.validity.overlaps]
    return {"outcome": result.outcome.value, "fails_at": fails_at(result),
            "events": [{"name": e.name, "state": e.state.value, "time": e.time} for e in events],
            "overlaps": overlaps, "sim_time": result.sim_time, "wall_time": result.wall_time}


def still_replay(scenario, scene, validity, title: str) -> Replay:
    """One frame of ``scene`` (a :class:`~rgmcad.scene.bodies.Scene` that was not simulated
    because its parts overlap), the overlapping bodies red and the others grey."""
    hot = {name for o in validity.overlaps for name in (o.first, o.second)}
    meshes, mesh_of, static, planes = scene_meshes(scene)
    solid = {name: body for name, body in scene.bodies.items() if not body.plane}
    names = list(solid)
    colors = [_OVERLAP if name in hot else _CLEAR_STATIC if body.static else _CLEAR_MOVING
              for name, body in solid.items()]
    poses = [np.asarray(body.pose, float) for body in solid.values()]
    labels = [scenario.objects[body.object].run or body.object  # as the viewer tags
              for body in solid.values()]
    events = tuple({"name": name, "after": list(spec.after), "join": spec.join,
                    "state": EventState.ASLEEP.value, "time": None, "description": spec.description}
                   for name, spec in scenario.events.items())
    return Replay(title=title, bodies=tuple(names), meshes=tuple(meshes),
                  mesh_of=np.asarray(mesh_of, int), static=np.asarray(static, bool),
                  colors=np.asarray(colors, float), planes=tuple(planes),
                  times=np.zeros(1), poses=np.stack(poses)[None],
                  events=events, outcome=Outcome.INVALID.value, labels=tuple(labels))


def _extent(replay: Replay, axis: np.ndarray) -> tuple[float, float]:
    """Lowest and highest coordinate of the replay's first frame along ``axis``."""
    along = [transform_points(replay.poses[0, b], replay.meshes[replay.mesh_of[b]][0]) @ axis
             for b in range(len(replay.bodies))]
    along = np.concatenate(along) if along else np.zeros(1)
    return float(along.min()), float(along.max())


def _aside(replays: tuple[Replay, Replay]) -> np.ndarray:
    """A world direction lying in every plane of the scene (the floor, a board), along which
    the second layout is moved beside the first: x if it can, else y."""
    normals = [p[:3, 2] for r in replays for p in r.planes]
    for axis in np.eye(3)[:2]:
        if all(abs(float(n @ axis)) < 1e-6 for n in normals):
            return axis
    return np.eye(3)[0]


def side_by_side(first: Replay, second: Replay, labels: tuple[str, str], title: str) -> Replay:
    """Two recorded layouts in one replay: ``second`` moved beside ``first`` along a
    direction in the floor's plane, so one camera frames both and one clock plays both. The
    longer run sets the frames; the shorter one holds its last pose after it stopped. Bodies
    and events are named ``LABEL: name``; planes both share are drawn once."""
    axis = _aside((first, second))
    lo_a, hi_a = _extent(first, axis)
    lo_b, hi_b = _extent(second, axis)
    gap = max(0.25 * max(hi_a - lo_a, hi_b - lo_b), 0.02)
    shift = translation(axis * (hi_a + gap - lo_b))
    times = first.times if len(first.times) >= len(second.times) else second.times

    def frames(r: Replay, move: np.ndarray | None) -> np.ndarray:
        at = np.clip(np.searchsorted(r.times, times + 1e-9, side="right") - 1, 0, len(r.times) - 1)
        poses = r.poses[at]
        return poses if move is None else np.einsum("ij,fbjk->fbik", move, poses)

    def named(r: Replay, label: str) -> tuple[dict, ...]:
        return tuple({**e, "name": f"{label}: {e['name']}",
                      "after": [f"{label}: {a}" for a in e["after"]]} for e in r.events)

    planes = list(first.planes)
    for p in second.planes:
        moved = shift @ p
        if not any(np.allclose(moved[:3, 2], q[:3, 2]) and abs(float((moved[:3, 3] - q[:3, 3])
                   @ q[:3, 2])) < 1e-9 for q in planes):
            planes.append(moved)
    a, b = labels
    both = first.outcome == second.outcome == Outcome.SUCCESS.value
    tags = None if first.labels is None or second.labels is None else (
        tuple(f"{a}: {t}" for t in first.labels) + tuple(f"{b}: {t}" for t in second.labels))
    return Replay(
        title=title, bodies=tuple(f"{a}: {n}" for n in first.bodies)
        + tuple(f"{b}: {n}" for n in second.bodies),
        meshes=first.meshes + second.meshes,
        mesh_of=np.concatenate([first.mesh_of, np.asarray(second.mesh_of) + len(first.meshes)]),
        static=np.concatenate([first.static, second.static]),
        colors=np.concatenate([first.colors, second.colors]), planes=tuple(planes),
        times=np.asarray(times, float),
        poses=np.concatenate([frames(first, None), frames(second, shift)], axis=1),
        events=named(first, a) + named(second, b),
        outcome=Outcome.SUCCESS.value if both else Outcome.FAILURE.value, labels=tags)


def viewer_html(replay: Replay, note: str = "") -> str:
    """The viewer's page of ``replay`` (what ``rgmcad simulate --html`` writes), with a line
    of ``note`` above it."""
    payload = replay_payload(replay)
    body = (f'<p class="muted">{escape(note)}</p>\n' if note else "") + replay_section(payload)
    return html_page(replay.title, body, payload)
