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
``x ± 3 mm`` or ``x -2/+4 mm`` (``roll ± 2°`` for angles). A parameter belongs to an object;
the parameters of a frame (a ``part = "frame"`` object such as ``bottom_track_joint`` or a
domino run) are printed, with the frame's name, beside every part placed through that frame
(its descendants in the ``parent`` chain).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rgmcad.geometry import ANGLE_KEYS, POSE_KEYS
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
    """

    name: str
    order: int
    vertices: np.ndarray
    faces: np.ndarray
    pose: np.ndarray
    tolerances: tuple[str, ...] = ()


@dataclass(frozen=True)
class BasePlane:
    """An infinite plane of the scenario (floor, board); never drawn.

    ``point`` (3,) metres and unit ``normal`` (3,), world coordinates.
    """

    name: str
    point: np.ndarray
    normal: np.ndarray


# --- tolerances -----------------------------------------------------------------------------------


def _number(v: float) -> str:
    s = f"{v:.1f}" if v >= 1.0 else f"{v:.2g}"
    return s.rstrip("0").rstrip(".") if "." in s else s


def format_tolerance(label: str, component: str, down: float, up: float) -> str:
    """``"x ± 3 mm"``, ``"x -2/+4 mm"`` or ``"roll ± 2°"`` from metres or degrees."""
    angle = component in ANGLE_KEYS
    factor, unit = (1.0, "°") if angle else (1000.0, " mm")
    d, u = _number(down * factor), _number(up * factor)
    if d == u:
        return f"{label} ± {d}{unit}"
    return f"{label} -{d}/+{u}{unit}"


def part_tolerances(scenario, obj_name: str, tolerances) -> tuple[str, ...]:
    """Notes for the body of object ``obj_name``: its own parameters first (``x ± 3 mm``),
    then those of the frames it is placed through (``bottom_track_joint.roll ± 2°``)."""
    notes = []
    chain = [obj_name]
    parent = scenario.objects[obj_name].parent
    while parent is not None:
        chain.append(parent)
        parent = scenario.objects[parent].parent
    for depth, name in enumerate(chain):
        if depth and scenario.objects[name].part != FRAME:
            continue
        for component in POSE_KEYS:
            key = f"{name}.{component}"
            if key in tolerances:
                label = component if depth == 0 else key
                notes.append(format_tolerance(label, component, *tolerances[key]))
    return tuple(notes)


# --- scene -> template inputs ---------------------------------------------------------------------


def placement_order(scenario, scene) -> list[str]:
    """Names of the scene's non-plane bodies in build order (see the module docstring)."""
    hinged = {h.moving for h in scene.hinges}
    trigger = set(scenario.events[scenario.root_event].objects.values())
    keys = {}
    for index, body in enumerate(scene.bodies.values()):
        if body.plane:
            continue
        tier = (0 if body.static else 1 if body.name in hinged
                else 3 if body.object in trigger else 2)
        lowest_mm = round(float(body.world_vertices()[:, 2].min()) * 1000.0)
        keys[body.name] = (tier, lowest_mm, index)
    return sorted(keys, key=keys.__getitem__)


def template_inputs(scenario, scene, tolerances=None) -> tuple[list[PlacedPart], list[BasePlane]]:
    """``(parts, base_planes)`` of a posed scene, parts in placement order.

    ``tolerances`` maps ``"object.component"`` to ``(down, up)`` in metres or degrees (see
    the module docstring); the notes go into each part's ``tolerances``.
    """
    tolerances = tolerances or {}
    order = {name: k + 1 for k, name in enumerate(placement_order(scenario, scene))}
    parts, planes = [], []
    for body in scene.bodies.values():
        pose = np.asarray(body.pose, float)
        if body.plane:
            planes.append(BasePlane(body.name, pose[:3, 3].copy(), pose[:3, 2].copy()))
            continue
        parts.append(PlacedPart(body.name, order[body.name], body.world_vertices(),
                                np.asarray(body.built.faces), pose,
                                part_tolerances(scenario, body.object, tolerances)))
    parts.sort(key=lambda p: p.order)
    return parts, planes
