"""What a template is drawn from: posed parts and base planes, and how a scene becomes them.

Placement order
---------------
The number printed beside each part is the order a person builds the layout in:

1. static parts (supports, tracks, walls, containers, a lever's axle): they hold the rest;
2. parts hinged on them (a lever's plank goes on its axle);
3. the other moving parts (planks, dominoes, a ball), which rest on what is already there;
4. last, the moving parts the chain starts with (the bodies of the root event: the leaning
   first domino, the ball that rolls first), so nothing sets the chain off early.

Within each tier the lowest part comes first (its lowest point, world Z, to the millimetre),
so a part standing on another one is placed after it; ties keep the scenario's file order
(a domino run stays in its order).

Tolerances
----------
A layout file (JSON or TOML) may carry placement tolerances in real units, as the optimiser
writes them (read by :func:`rgmcad.scene.layout_files.read_tolerances`)::

    "tolerances": {"top_track.x": [0.002, 0.004], "goblet.roll": [1.5, 1.5]}

``[down, up]`` (metres or degrees; signs are ignored; one number means symmetric) is how far
below and above its value the parameter may be placed. They are printed beside the part as
``x ± 3 mm`` or ``x -2/+4 mm`` (``roll ± 2°`` for angles). The optimiser reports the
distance to the end of the parameter's range where the learned model shows no drop; such a
side is printed as "not limiting within the range" rather than as a sensitivity.

The parameters of a frame (a ``part = "frame"`` object such as ``bottom_track_joint`` or a
domino run) are stated once, at the frame's origin on the drawing (:class:`FrameNote`),
an angle also as the millimetres it moves the frame's farthest part.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rgmcad.geometry import ANGLE_KEYS, POSE_KEYS
from rgmcad.making.steps import placement_order  # the build order, shared with the steps
from rgmcad.scene.model import FRAME


@dataclass(frozen=True, eq=False)
class PlacedPart:
    """One posed part of a layout.

    Attributes
    ----------
    name : str
        e.g. ``"track"``, ``"run[3]"``.
    order : int
        Placement order, 1-based.
    vertices : (n, 3) float
        The part's exact CAD mesh in world coordinates, metres.
    faces : (m, 3) int
        Triangles of the mesh.
    pose : (4, 4) float
        World pose of the part's frame (metres).
    tolerances : tuple of str
        Ready-made notes, e.g. ``"x ± 3 mm"``.
    fall : (3,) float or None
        World direction the part falls in (a domino of a run: its local +X), else None.
    """

    name: str
    order: int
    vertices: np.ndarray
    faces: np.ndarray
    pose: np.ndarray
    tolerances: tuple[str, ...] = ()
    fall: np.ndarray | None = None


@dataclass(frozen=True, eq=False)
class FrameNote:
    """A frame's tolerances, stated once at its origin.

    ``origin`` (3,) world metres; ``notes`` e.g. ``("switch_run (9 parts)", "y ± 3 mm")``.
    """

    name: str
    origin: np.ndarray
    notes: tuple[str, ...]


@dataclass(frozen=True)
class BasePlane:
    """An infinite plane of the scenario (floor, board); never drawn.

    ``point`` (3,) metres and unit ``normal`` (3,), world coordinates.
    """

    name: str
    point: np.ndarray
    normal: np.ndarray


# --- tolerances -----------------------------------------------------------------------------------


def _number(v: float, down: bool = True) -> str:
    """Millimetres or degrees as a maker reads them: to 0.1 (rounded down, as a tolerance
    must be, unless ``down`` is False), no trailing zeros, never in scientific notation
    (``6.1e-05`` was printed for a side with no room)."""
    from rgmcad.runs.report import tolerance_text

    text = tolerance_text(abs(v)) if down else f"{abs(v):.1f}"
    return text.rstrip("0").rstrip(".")


def format_tolerance(label: str, component: str, down: float, up: float,
                     room: tuple[float, float] | None = None, push: dict | None = None) -> str:
    """``"x ± 3 mm"``, ``"x -2/+4 mm"`` or ``"roll ± 2°"`` from metres or degrees.

    ``room`` is the distance from the value to each end of its range: a side whose
    tolerance reaches it is not limited by the model, and is printed so. ``push``:
    ``{"low" | "high": part}``, the sides where the part is pushed against another (and
    works there): printed so, without a number.
    """
    angle = component in ANGLE_KEYS
    factor, unit = (1.0, "°") if angle else (1000.0, " mm")
    if push:
        words = {"low": "below", "high": "above"}
        sides = [f"{words[side]}: push against the {part}" for side, part in push.items()]
        if len(push) == 2:
            return f"{label}: " + "; ".join(sides)
        other = _number((up if "low" in push else down) * factor)
        return f"{label} {'+' if 'low' in push else '-'}{other}{unit}; {sides[0]}"
    # the optimiser reports exactly the room left where the model shows no drop
    free = [room is not None and r > 0 and abs(t - r) <= 1e-6 * max(1.0, r) for t, r in zip(
        (down, up), room or (0.0, 0.0), strict=True)]
    if all(free):
        return f"{label}: not limiting within the range"
    d, u = _number(down * factor), _number(up * factor)
    if d == u == "0":
        return f"{label}: exactly (no room either way)"
    if d == "0" and not free[1]:
        return f"{label} +{u}{unit}, not below"
    if u == "0" and not free[0]:
        return f"{label} -{d}{unit}, not above"
    if free[0]:
        return f"{label} +{u}{unit} (below: not limiting within the range)"
    if free[1]:
        return f"{label} -{d}{unit} (above: not limiting within the range)"
    if d == u:
        return f"{label} ± {d}{unit}"
    return f"{label} -{d}/+{u}{unit}"


def _rooms(scenario, values) -> dict[str, tuple[float, float]]:
    """``{"object.component": (value - low, high - value)}`` of the free parameters."""
    if values is None:
        return {}
    return {f.name: (float(v) - f.low, f.high - float(v))
            for f, v in zip(scenario.free, np.asarray(values, float), strict=True)}


def part_tolerances(scenario, obj_name: str, tolerances, rooms=None,
                    push=None) -> tuple[str, ...]:
    """Notes for the body of object ``obj_name``: its own parameters (``x ± 3 mm``)."""
    rooms, push = rooms or {}, push or {}
    notes = []
    for component in POSE_KEYS:
        key = f"{obj_name}.{component}"
        if key in tolerances:
            notes.append(format_tolerance(component, component, *tolerances[key],
                                          rooms.get(key), push.get(key)))
    return tuple(notes)


def frame_notes(scenario, scene, tolerances, rooms=None, push=None) -> list[FrameNote]:
    """A :class:`FrameNote` per frame with tolerances: translations as they are, angles also
    as the displacement of the frame's farthest part (mm) that the angle makes."""
    from rgmcad.scene.design_space import world_poses

    rooms, push = rooms or {}, push or {}
    poses = world_poses(scenario, scene.values)
    out = []
    for name, obj in scenario.objects.items():
        keys = [c for c in POSE_KEYS if f"{name}.{c}" in tolerances]
        if obj.part != FRAME or not keys:
            continue
        pose = poses[name]
        below = []
        for body in scene.bodies.values():
            chain, parent = [], body.object
            while parent is not None:
                chain.append(parent)
                parent = scenario.objects[parent].parent
            if name in chain[1:] or (body.object == name):
                below.append(body.world_vertices())
        notes = [f"{name}: frame of {len(below)} part{'s' if len(below) != 1 else ''}"]
        pts = np.concatenate(below) if below else pose[:3, 3][None]
        for c in keys:
            down, up = tolerances[f"{name}.{c}"]
            text = format_tolerance(c, c, down, up, rooms.get(f"{name}.{c}"),
                                    push.get(f"{name}.{c}"))
            if c in ANGLE_KEYS and "not limiting" not in text and "push" not in text:
                axis = pose[:3, {"heading": 2, "pitch": 0, "roll": 1}[c]]
                d = pts - pose[:3, 3]
                reach = float(np.max(np.linalg.norm(d - np.outer(d @ axis, axis), axis=1)))
                mm = [_number(1000.0 * reach * np.radians(t)) for t in (down, up)]
                size = f"± {mm[0]}" if mm[0] == mm[1] else f"-{mm[0]}/+{mm[1]}"
                text = (f"turn {size} mm at its far end, {_number(1000 * reach, down=False)} mm from its "
                        f"origin ({text})")
            notes.append(text)
        out.append(FrameNote(name, pose[:3, 3].copy(), tuple(notes)))
    return out


# --- scene -> template inputs ---------------------------------------------------------------------


def with_supports(parts, stands) -> list[PlacedPart]:
    """``parts`` with each stand (:class:`~rgmcad.making.stands.Stand`) drawn as a part,
    placed first (a stand goes down before what it holds): ``S1 support of track``, its
    size and heights as its note."""
    if not stands:
        return list(parts)
    out = []
    for k, stand in enumerate(stands):
        mesh = stand.mesh()
        length, width = stand.size
        h = stand.heights() * 1000
        note = f"stand {length * 1000:.1f} x {width * 1000:.1f} mm, {h.min():.1f}-{h.max():.1f} mm"
        out.append(PlacedPart(f"{stand.label} support of {stand.part}", k + 1,
                              np.asarray(mesh.vertices), np.asarray(mesh.faces),
                              stand.frame.copy(), (note,)))
    return out + [replace(p, order=p.order + len(out)) for p in parts]


def template_inputs(scenario, scene, tolerances=None, push=None):
    """``(parts, base_planes, frames)`` of a posed scene, parts in placement order.

    ``tolerances`` maps ``"object.component"`` to ``(down, up)`` in metres or degrees (see
    the module docstring); a part's own go into its ``tolerances``, a frame's into a
    :class:`FrameNote`; ``push`` maps some of them to ``{"low" | "high": part}``, the sides
    where the part is pushed against another instead.
    """
    tolerances = tolerances or {}
    rooms = _rooms(scenario, getattr(scene, "values", None))
    order = {name: k + 1 for k, name in enumerate(placement_order(scenario, scene))}
    parts, planes = [], []
    for body in scene.bodies.values():
        pose = np.asarray(body.pose, float)
        if body.plane:
            planes.append(BasePlane(body.name, pose[:3, 3].copy(), pose[:3, 2].copy()))
            continue
        run = getattr(scenario.objects[body.object], "run", None)
        parts.append(PlacedPart(body.name, order[body.name], body.world_vertices(),
                                np.asarray(body.built.faces), pose,
                                part_tolerances(scenario, body.object, tolerances, rooms,
                                                push),
                                pose[:3, 0].copy() if run else None))
    parts.sort(key=lambda p: p.order)
    return parts, planes, frame_notes(scenario, scene, tolerances, rooms, push)
