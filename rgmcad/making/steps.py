"""Numbered assembly steps of a layout, in the template's placement order, and a picture of
the machine after each.

The order is the template's (:func:`placement_order`, whose numbers label the parts on the
printed sheets): static parts, then parts hinged on them, the other moving parts, and last
the parts the chain starts with; within each tier the lowest part first. Steps group it so a
person can follow them:

* a support (:mod:`rgmcad.making.supports`, once given) comes right before the part it holds;
* the dominoes of a run are one step, where the run's first domino in the order is placed (at
  the end when one of them starts the chain, so nothing sets it off early);
* every other part is a step of its own;
* a rope comes right after the step that places the last of the parts it is tied to or runs
  over.

Every part is placed exactly once, and never before a part it rests on (:func:`rests_on`).
Each step's picture (:func:`render_steps`) shows the parts placed so far from the template's
side of its plane, those of the step in orange and the earlier ones in grey.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TOUCH_M = 0.003
"""Gap (m) at or below which two parts count as touching for :func:`rests_on` (a part
set this close above another drops onto it: the shipped ball starts 2 mm above its track)."""
NEW = (0.93, 0.42, 0.05, 1.0)
"""Colour (RGBA) of the parts a step places, in its picture."""
EARLIER = (0.55, 0.55, 0.58, 1.0)
"""Colour (RGBA) of the parts placed before, in a step's picture."""
_FAR = 1.0e4  # m: where a part not placed yet is put out of the picture


def placement_order(scenario, scene) -> list[str]:
    """Names of the scene's non-plane bodies in build order (the template's numbers; see the
    module docstring of :mod:`rgmcad.printing.inputs`)."""
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


@dataclass(frozen=True)
class Support:
    """A support to place before the part it holds: ``name``, ``holds`` the body name of
    that part, and ``what`` it is (size and height, for a person)."""

    name: str
    holds: str
    what: str = ""


def supports_of(stands) -> list[Support]:
    """The :class:`Support` of each stand of :mod:`rgmcad.making.stands` (its ``part`` is the
    name of the static part's first object, the name of that object's main body)."""
    return [Support(s.label, s.part, s.describe()) for s in stands]


@dataclass(frozen=True)
class Step:
    """One assembly step.

    Attributes
    ----------
    number : int
        1-based.
    kind : str
        ``"support"``, ``"part"``, ``"run"`` (a domino run) or ``"rope"``.
    bodies : tuple of str
        Scene bodies placed in this step (none for a support or a rope).
    orders : tuple of int
        Their numbers on the template (placement order, 1-based).
    rope : str or None
        The rope tied in this step.
    support : str or None
        The support placed in this step.
    text : str
        What to do, for a person.
    """

    number: int
    kind: str
    bodies: tuple[str, ...] = ()
    orders: tuple[int, ...] = ()
    rope: str | None = None
    support: str | None = None
    text: str = ""

    def to_json(self) -> dict:
        return {"number": self.number, "kind": self.kind, "bodies": list(self.bodies),
                "orders": list(self.orders), "rope": self.rope, "support": self.support,
                "text": self.text}


def _numbers(orders: Sequence[int]) -> str:
    """``"4"``, ``"4, 5"``, ``"4-9, 12"``: runs of three or more consecutive numbers as
    ranges."""
    spans: list[list[int]] = []
    for o in orders:
        if spans and o == spans[-1][-1] + 1:
            spans[-1].append(o)
        else:
            spans.append([o])
    return ", ".join(f"{s[0]}-{s[-1]}" if len(s) > 2 else ", ".join(map(str, s)) for s in spans)


def _route(objects: Sequence[str | None]) -> str:
    """``"cage -> 2 pulleys -> gate"``: a rope's ends (``a fixed point`` for the world) and
    how many points it runs over between them."""
    ends = [o or "a fixed point" for o in (objects[0], objects[-1])]
    k = len(objects) - 2
    return " -> ".join([ends[0], *([f"{k} pulle{'ys' if k > 1 else 'y'}"] if k else []), ends[1]])


def assembly_steps(scenario, scene, supports: Sequence[Support] = (),
                   where: Mapping[str, Sequence[str]] | None = None) -> tuple[Step, ...]:
    """The numbered steps of building ``scene`` (a posed layout of ``scenario``).

    ``supports``: supports to place right before the part each holds (their bodies are not
    in the scene); the template draws them first, numbered 1, 2, ... in this order, and the
    parts after them, so the parts' numbers here are shifted as there. ``where``: body name
    -> labels of the template sheets it is drawn on, named in the steps' text.
    """
    order = placement_order(scenario, scene)
    number = {name: k + 1 + len(supports) for k, name in enumerate(order)}
    support_number = {s.name: k + 1 for k, s in enumerate(supports)}
    where = where or {}
    trigger = set(scenario.events[scenario.root_event].objects.values())
    runs = {name: run for run, names in scenario.runs.items() for name in names}
    groups: list[tuple[str, list[str], str | None]] = []  # (kind, bodies, run)
    run_group: dict[str, list[str]] = {}
    for name in order:
        obj = scene.bodies[name].object
        run = runs.get(obj)
        if run is None:
            groups.append(("part", [name], None))
        elif run not in run_group:
            run_group[run] = [name]
            groups.append(("run", run_group[run], run))
        else:
            run_group[run].append(name)
    # a run with the domino that starts the chain goes last
    starts = [g for g in groups if g[0] == "run" and any(
        scene.bodies[b].object in trigger for b in g[1])]
    groups = [g for g in groups if g not in starts] + starts
    held = {}
    for s in supports:
        held.setdefault(s.holds, []).append(s)
    placed_objects: set[str] = set()
    ropes = list(scene.ropes)
    steps: list[Step] = []

    def add(**kw):
        steps.append(Step(number=len(steps) + 1, **kw))

    for s in supports:  # under a part the scene does not have: first
        if s.holds not in number:
            add(kind="support", support=s.name, orders=(support_number[s.name],),
                text=f"Stand the support {support_number[s.name]}. {s.name} on its footprint"
                     f" ({s.what or s.holds}).")
    for kind, bodies, run in groups:
        for body in bodies:
            for s in held.get(body, ()):
                what = f" ({s.what})" if s.what else ""
                add(kind="support", support=s.name, orders=(support_number[s.name],),
                    text=f"Stand the support {support_number[s.name]}. {s.name} on its "
                         "footprint, under "
                         f"{number[body]}. {body}{what}.")
        orders = tuple(number[b] for b in bodies)
        sheets = sorted({label for b in bodies for label in where.get(b, ())})
        on = f" (sheet {', '.join(sheets)})" if sheets else ""
        if kind == "run":
            first = next((b for b in bodies if scene.bodies[b].object in trigger), None)
            last = f"; stand {number[first]}. {first} last: it starts the chain" if first else ""
            text = (f"Stand the {len(bodies)} dominoes of run {run}, {_numbers(orders)}, on "
                    f"their outlines{on}, each facing the way its arrow falls{last}.")
        else:
            body = bodies[0]
            below = [b for b in rests_on_body(scene, body, [x for s in steps for x in s.bodies])]
            rest = f", on {', '.join(f'{number[b]}. {b}' for b in below)}" if below else ""
            verb = "Fix" if scene.bodies[body].static else "Place"
            text = f"{verb} {number[body]}. {body} on its outline{on}{rest}."
        add(kind=kind, bodies=tuple(bodies), orders=orders, text=text)
        placed_objects.update(scene.bodies[b].object for b in bodies)
        for rope in list(ropes):
            needs = {o for o in rope.objects if o is not None and o in scene.bodies}
            if needs <= placed_objects:
                ropes.remove(rope)
                add(kind="rope", rope=rope.name,
                    text=f"Tie rope {rope.name} ({rope.length * 1000:.0f} mm between the "
                         f"knots): {_route(rope.objects)}.")
    for rope in ropes:  # tied to nothing that is placed (world points only)
        add(kind="rope", rope=rope.name, text=f"Tie rope {rope.name} "
            f"({rope.length * 1000:.0f} mm between the knots).")
    return tuple(steps)


# --- what rests on what ------------------------------------------------------------------------


def _piece_distances(piece, points: np.ndarray) -> np.ndarray:
    """(n,) signed distances (m) of ``points`` (n, 3), in the piece's frame, to a collision
    piece; a convex hull's by its faces' planes (exact against its faces, less near edges)."""
    from rgmcad.parts.pieces import ConvexPiece
    from rgmcad.sim.distances import signed_distances

    if isinstance(piece, ConvexPiece):
        from scipy.spatial import ConvexHull

        eq = ConvexHull(np.asarray(piece.vertices, float)).equations
        return (points @ eq[:, :3].T + eq[:, 3]).max(axis=1)
    return signed_distances(piece, points)


UP = 0.5
"""A contact whose normal has at least this upward component (cosine) holds the upper part."""


def _contacts(pts: np.ndarray, q, gap: float) -> np.ndarray:
    """(k, 3) world normals of body ``q``'s collision pieces at those of the world points
    ``pts`` (n, 3) that lie within ``gap`` m of them (gradients of the signed distance)."""
    from rgmcad.geometry import invert, transform_points

    out = []
    eps = 1e-5
    for piece in q.built.pieces:
        frame = q.pose @ piece.frame
        local = transform_points(invert(frame), pts)
        near = local[_piece_distances(piece, local) <= gap]
        if not len(near):
            continue
        grad = np.stack([_piece_distances(piece, near + eps * e)
                         - _piece_distances(piece, near - eps * e) for e in np.eye(3)], axis=1)
        grad /= np.maximum(np.linalg.norm(grad, axis=1, keepdims=True), 1e-12)
        out.append(grad @ frame[:3, :3].T)
    return np.vstack(out) if out else np.zeros((0, 3))


def _held_from_below(a, b, gap: float) -> bool:
    """Whether body ``b`` holds body ``a`` up: they come within ``gap`` m (a vertex of one's
    mesh near a collision piece of the other) where ``b``'s surface faces up (or ``a``'s
    faces down), at least :data:`UP`."""
    va, vb = a.world_vertices(), b.world_vertices()
    if np.any(va.min(0) > vb.max(0) + gap) or np.any(vb.min(0) > va.max(0) + gap):
        return False
    if np.any(_contacts(va, b, gap)[:, 2] >= UP):
        return True
    return bool(np.any(_contacts(vb, a, gap)[:, 2] <= -UP))


def rests_on_body(scene, name: str, candidates: Sequence[str], gap: float = TOUCH_M) -> list[str]:
    """Those of ``candidates`` (body names) that body ``name`` rests on: their lowest point
    is lower (to the millimetre) and they hold it from below, within ``gap`` m (a part
    leaning against another sideways rests on neither, nor do blocks side by side). A hinged
    body hangs on its axle: it rests on static bodies only."""
    body = scene.bodies[name]
    hinged = any(h.moving == name for h in scene.hinges)
    low = round(float(body.world_vertices()[:, 2].min()) * 1000.0)
    out = []
    for other in candidates:
        b = scene.bodies[other]
        if other == name or b.plane or b.object == body.object or (hinged and not b.static):
            continue
        lower = round(float(b.world_vertices()[:, 2].min()) * 1000.0) < low
        if lower and _held_from_below(body, b, gap):
            out.append(other)
    return out


def rests_on(scene, gap: float = TOUCH_M) -> dict[str, list[str]]:
    """Body name -> the bodies it rests on (:func:`rests_on_body`), for every non-plane body."""
    names = [n for n, b in scene.bodies.items() if not b.plane]
    return {n: rests_on_body(scene, n, names, gap) for n in names}


# --- pictures ------------------------------------------------------------------------------------


def default_view(scene) -> tuple[np.ndarray, np.ndarray]:
    """``(normal, up)``: the side a template of ``scene`` is seen from by default (a vertical
    base plane's front, else from above with world +Y up on the page)."""
    for body in scene.bodies.values():
        if body.plane and abs(body.pose[2, 2]) < 0.5:
            return body.pose[:3, 2].copy(), np.array([0.0, 0.0, 1.0])
    return np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])


def _fit(scene, centre, direction, up, fov: float, aspect: float):
    """``(eye, distance)`` of a camera looking at ``centre`` from ``direction`` that just
    frames every part (a vertical field of view of ``fov`` degrees)."""
    points = np.vstack([b.world_vertices() for b in scene.bodies.values() if not b.plane])
    d = points - centre
    right = np.cross(-direction, up)
    right /= np.linalg.norm(right)
    cam_up = np.cross(right, -direction)
    tan_v = np.tan(np.radians(fov / 2))
    half = max(np.abs(d @ right).max() / (tan_v * aspect), np.abs(d @ cam_up).max() / tan_v)
    distance = float((d @ direction).max() + 1.08 * half)
    return centre + direction * distance, distance


def render_steps(scenario, scene, steps: Sequence[Step], normal=None, up=None,
                 width: int = 480, height: int = 360, stands=()) -> list[np.ndarray]:
    """One (height, width, 3) uint8 picture per step: the parts placed up to it, seen from
    the ``normal`` side of the template plane with ``up`` (world directions) up on the
    picture (default: :func:`default_view`), a little from the builder's side; the step's
    own parts in orange (:data:`NEW`), the earlier ones grey. The camera frames the whole layout in
    every picture. ``stands`` (:mod:`rgmcad.making.stands`) are drawn from their steps on."""
    from rgmcad.scene.palette import runs_of
    from rgmcad.sim.engine import pb
    from rgmcad.sim.render import Renderer

    if normal is None or up is None:
        normal, up = default_view(scene)
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    up = np.asarray(up, float) / np.linalg.norm(up)
    renderer = Renderer(scene, width, height, runs_of(scenario), supersample=False)
    try:
        horizontal = abs(normal[2]) > 0.9
        direction = normal - 0.45 * up if horizontal else normal + 0.2 * up
        direction /= np.linalg.norm(direction)
        centre = (renderer.lo + renderer.hi) / 2
        fov = 40.0
        eye, distance = _fit(scene, centre, direction, up, fov, width / height)
        renderer.view = pb.computeViewMatrix(eye.tolist(), centre.tolist(), up.tolist())
        renderer.projection = pb.computeProjectionMatrixFOV(fov, width / height, distance / 20,
                                                            distance * 3)
        renderer.light = (direction + 0.5 * up).tolist()
        far = np.eye(4)
        far[:3, 3] = _FAR
        for stand in stands:  # world vertices, drawn at the origin (or far away)
            mesh = stand.mesh()
            shape = renderer.engine.createVisualShape(
                pb.GEOM_MESH, vertices=mesh.vertices.tolist(),
                indices=np.asarray(mesh.faces).ravel().tolist(), rgbaColor=EARLIER)
            renderer.ghosts[stand.label] = renderer.engine.createMultiBody(0, -1, shape)
            renderer.colours[stand.label] = EARLIER[:3]
        origin = np.eye(4)
        labels = {s.label for s in stands}
        placed: set[str] = set()
        tied: set[str] = set()
        out = []
        for step in steps:
            for name in placed:
                renderer.engine.changeVisualShape(renderer.ghosts[name], -1, rgbaColor=EARLIER)
            new = (*step.bodies, *([step.support] if step.support in labels else []))
            for name in new:
                renderer.engine.changeVisualShape(renderer.ghosts[name], -1, rgbaColor=NEW)
            placed.update(new)
            if step.rope:
                tied.add(step.rope)
            renderer.place({n: (far if n not in placed else origin if n in labels
                                else scene.bodies[n].pose) for n in renderer.ghosts})
            for rope, beads in renderer.ropes:
                if rope.name not in tied:
                    for bead in beads:
                        renderer.engine.resetBasePositionAndOrientation(bead, [_FAR] * 3,
                                                                        [0, 0, 0, 1])
            out.append(renderer.image())
        return out
    finally:
        renderer.close()
