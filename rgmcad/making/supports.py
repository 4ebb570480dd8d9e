"""Which static parts of a layout are raised, and where the plane lies that a stand holds
them from.

A *static part* is a static body of the scene, or a group of static bodies that are welded
together or make one fixed part (a static lever, a lever's axle); a hinged part's fixed base
is one. It is *held* when its lowest point is within ``touch`` of a base plane (the floor, a
board), or when it touches a part that is held. Every other static part is *raised*: it
floats in the simulation and needs a support when built.

A scenario without base planes (the paper's ``teapot`` and ``long_chain``, machines in the
XZ plane) is built against a *virtual board*: the plane behind the layout across its
thinnest extent, on the far side from the template's viewer (``xz`` seen from -Y: the
board at the largest y), or, for a layout that is not flat, a virtual floor under its lowest
point.

Lengths are metres, world frame Z up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import ConvexHull

from rgmcad.geometry import invert, matmul, transform_points
from rgmcad.parts.pieces import ConvexPiece
from rgmcad.scene.bodies import Scene
from rgmcad.sim.distances import signed_distances

__all__ = ["BasePlane", "StaticPart", "Holding", "base_planes", "static_parts", "holdings",
           "raised_parts", "TOUCH"]

TOUCH = 0.001
"""m: a part this close to a base plane or to a held part rests on it."""


@dataclass(frozen=True, eq=False)
class BasePlane:
    """A plane stands rest on: ``point`` (3,) m on it, ``normal`` (3,) unit, towards the
    parts. ``virtual``: not in the scenario, placed behind the layout (see the module)."""

    name: str
    point: np.ndarray
    normal: np.ndarray
    virtual: bool = False
    outline: np.ndarray | None = None
    """(k, 2) world x, y of a shelf's edge (the flat top of a held part), None: unbounded."""
    bodies: tuple[str, ...] = ()
    """A shelf's bodies (the held part's)."""

    def on(self, points: np.ndarray, inset: float = 0.0) -> np.ndarray:
        """(n,) bool: whether world points (n, 3) stand on the plane's area (``inset`` m
        from a shelf's edge); always true on an unbounded plane."""
        if self.outline is None:
            return np.ones(len(points), bool)
        import shapely

        area = shapely.Polygon(self.outline).buffer(-inset)
        return shapely.contains_xy(area, points[:, 0], points[:, 1])

    @property
    def horizontal(self) -> bool:
        return self.normal[2] > 0.99

    def gap(self, points: np.ndarray) -> float:
        """m: the smallest signed distance of (n, 3) points from the plane."""
        return float(np.min((np.asarray(points, float) - self.point) @ self.normal))

    def frame(self) -> np.ndarray:
        """(4, 4) world transform of the plane's frame: origin ``point``, z the normal, x a
        horizontal direction where there is one (else world x)."""
        z = self.normal
        x = np.cross([0.0, 0.0, 1.0], z)
        x = np.array([1.0, 0.0, 0.0]) if np.linalg.norm(x) < 1e-9 else x / np.linalg.norm(x)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x, np.cross(z, x), z, self.point
        return m


@dataclass(frozen=True)
class StaticPart:
    """One rigid static part as a maker places it: ``name`` (its first object's name),
    ``bodies`` (scene body names) and ``objects`` (scenario objects), in scene order."""

    name: str
    bodies: tuple[str, ...]
    objects: tuple[str, ...]


@dataclass(frozen=True)
class Holding:
    """What holds a static part: ``held_by`` a base plane's name, ``"part NAME"`` for a
    held part it touches, or ``""`` when it is raised; ``gap`` (m) from its nearest base
    plane ``base`` (the one a stand would rest on)."""

    part: StaticPart
    held_by: str
    gap: float
    base: BasePlane

    @property
    def raised(self) -> bool:
        return not self.held_by


def base_planes(scene: Scene) -> list[BasePlane]:
    """The scene's infinite planes as base planes, or one virtual plane when it has none."""
    out = [BasePlane(name, b.pose[:3, 3].copy(), b.pose[:3, 2] / np.linalg.norm(b.pose[:3, 2]))
           for name, b in scene.bodies.items() if b.plane]
    if out:
        return out
    pts = np.concatenate([b.world_vertices() for b in scene.bodies.values() if not b.plane])
    low, high = pts.min(0), pts.max(0)
    ext = high - low
    if ext[1] < 0.25 * min(ext[0], ext[2]):  # flat in y: seen from -Y, the board behind
        return [BasePlane("virtual board", np.array([0.0, high[1], 0.0]),
                          np.array([0.0, -1.0, 0.0]), True)]
    if ext[0] < 0.25 * min(ext[1], ext[2]):  # flat in x: seen from +X, the board behind
        return [BasePlane("virtual board", np.array([low[0], 0.0, 0.0]),
                          np.array([1.0, 0.0, 0.0]), True)]
    return [BasePlane("virtual floor", np.array([0.0, 0.0, low[2]]),
                      np.array([0.0, 0.0, 1.0]), True)]


def static_parts(scene: Scene) -> list[StaticPart]:
    """The static parts (see the module), in scene order; planes excluded."""
    group_of = {n: g for g in scene.welds for n in g}
    out, seen = [], set()
    for name, body in scene.bodies.items():
        if name in seen or body.plane:
            continue
        group = group_of.get(name, (name,))
        seen.update(group)
        if not all(scene.bodies[n].static for n in group):
            continue
        objects = tuple(dict.fromkeys(scene.bodies[n].object for n in group))
        out.append(StaticPart(objects[0], tuple(group), objects))
    # a hinged part's base is static, its moving body is not: the base alone is a part
    return out


def holdings(scene: Scene, planes: list[BasePlane] | None = None, *,
             touch: float = TOUCH) -> list[Holding]:
    """What holds each static part of ``scene`` (see :class:`Holding`), in scene order."""
    planes = base_planes(scene) if planes is None else planes
    parts = static_parts(scene)
    points = {p.name: np.concatenate([scene.bodies[n].world_vertices() for n in p.bodies])
              for p in parts}
    held: dict[str, str] = {}
    nearest: dict[str, tuple[float, BasePlane]] = {}
    for p in parts:
        gaps = [(plane.gap(points[p.name]), plane) for plane in planes]
        gaps = [(g, plane) for g, plane in gaps if g > -touch] or gaps
        nearest[p.name] = min(gaps, key=lambda gp: gp[0])
        if nearest[p.name][0] <= touch:
            held[p.name] = nearest[p.name][1].name
    changed = True
    while changed:  # resting on (touching) a held part holds a part too
        changed = False
        for p in parts:
            if p.name in held:
                continue
            other = next((q.name for q in parts if q.name in held
                          and _touching(scene, p, q, touch)), None)
            if other is not None:
                held[p.name] = f"part {other}"
                changed = True
    for p in parts:  # a raised part over the flat top of a held part: a shelf to stand on
        if p.name not in held:
            shelf = _shelf(points, p, [q for q in parts if q.name in held])
            if shelf is not None and shelf[0] < nearest[p.name][0]:
                nearest[p.name] = shelf
    return [Holding(p, held.get(p.name, ""), *nearest[p.name]) for p in parts]


def _shelf(points, part: StaticPart, held: list[StaticPart]):
    """(gap, BasePlane) of the highest flat top of a held part right under ``part``'s
    middle, or None."""
    from scipy.spatial import ConvexHull

    pts = points[part.name]
    low, middle = pts[:, 2].min(), pts[:, :2].mean(0)
    best = None
    for q in held:
        other = points[q.name]
        top = other[:, 2].max()
        face = other[other[:, 2] >= top - 2e-4, :2]
        if top >= low - TOUCH or len(face) < 3 or (best and top <= best[1].point[2]):
            continue
        try:
            hull = face[ConvexHull(face).vertices]
        except Exception:  # noqa: BLE001 - a degenerate (line) top is no shelf
            continue
        plane = BasePlane(f"top of {q.name}", np.array([0.0, 0.0, top]),
                          np.array([0.0, 0.0, 1.0]), outline=hull, bodies=q.bodies)
        if plane.on(np.array([[*middle, top]]))[0]:
            best = (float(low - top), plane)
    return best


def raised_parts(scene: Scene, planes: list[BasePlane] | None = None) -> list[Holding]:
    """The holdings of the raised static parts only."""
    return [h for h in holdings(scene, planes) if h.raised]


def _touching(scene: Scene, p: StaticPart, q: StaticPart, touch: float) -> bool:
    """Whether parts ``p`` and ``q`` come within ``touch`` of each other: a vertex of one
    within ``touch`` of the other's convex collision pieces (exact for boxes, cylinders,
    spheres; a convex piece by its hull's planes)."""
    a = np.concatenate([scene.bodies[n].world_vertices() for n in p.bodies])
    b = np.concatenate([scene.bodies[n].world_vertices() for n in q.bodies])
    lo, hi = np.maximum(a.min(0), b.min(0)), np.minimum(a.max(0), b.max(0))
    if np.any(lo > hi + touch):
        return False
    return (_near(scene, q, a, touch) or _near(scene, p, b, touch))


def _near(scene: Scene, part: StaticPart, points: np.ndarray, touch: float) -> bool:
    for name in part.bodies:
        body = scene.bodies[name]
        for piece in body.built.pieces:
            local = transform_points(invert(matmul(body.pose, piece.frame)), points)
            if isinstance(piece, ConvexPiece):  # the hull's planes: a lower bound outside
                planes = ConvexHull(np.asarray(piece.vertices, float)).equations
                d = (local @ planes[:, :3].T + planes[:, 3]).max(axis=1)
            else:
                d = signed_distances(piece, local)
            if float(d.min()) <= touch:
                return True
    return False
