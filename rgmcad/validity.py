"""Physical validity of a layout: do any two bodies intersect at the start?

Exact, on the parts' CAD meshes: every pair of distinct bodies that may collide (static pairs
included, jointed pairs excluded) whose bounding boxes overlap is intersected with manifold3d.
An intersection counts as a penetration of depth ``t``, the thickness of the intersection solid
along its thinnest direction (its smallest principal axis): exact for the slab two flat faces
make and for the cap a ball sinks into a plane. A body against an infinite plane is tested
exactly by the signed distances of its vertices, and a ball against a part made of box, sphere
and cylinder pieces (which tile it exactly) by the distances of its centre to those pieces.

The layout is valid when no penetration is deeper than ``tolerance`` (default 0.2 mm): bodies
that touch are valid, a 0.5 mm overlap is not. The paper summed Bullet's contact depths against
1 mm, which let thin parts overlap by most of their thickness.
"""

from __future__ import annotations

from dataclasses import dataclass

import manifold3d
import numpy as np

from rgmcad.geometry import invert, transform_points
from rgmcad.partlib import BoxPiece, CylinderPiece, SpherePiece
from rgmcad.scene import Scene, SceneBody

TOLERANCE = 2e-4
"""Deepest penetration (m) still counted as touching."""


@dataclass(frozen=True)
class Overlap:
    first: str
    second: str
    depth: float  # m
    volume: float  # m^3 (0 against a plane or when a ball is tested analytically)


@dataclass(frozen=True)
class Validity:
    valid: bool
    overlaps: tuple[Overlap, ...]  # every pair that penetrates deeper than the tolerance
    pairs_tested: int  # exact tests after bounding-box pruning

    @property
    def penetration(self) -> float:
        """Sum of the penetration depths beyond the tolerance (m); 0 for a valid layout."""
        return float(sum(o.depth for o in self.overlaps))


_MANIFOLDS: dict[int, tuple[object, manifold3d.Manifold]] = {}


def _manifold(body: SceneBody) -> manifold3d.Manifold:
    """The body's mesh as a Manifold, built once per process and per built body."""
    key = id(body.built)
    cached = _MANIFOLDS.get(key)
    if cached is None or cached[0] is not body.built:
        mesh = manifold3d.Mesh(
            vert_properties=np.asarray(body.built.vertices, np.float32),
            tri_verts=np.asarray(body.built.faces, np.uint32),
        )
        cached = (body.built, manifold3d.Manifold(mesh))
        _MANIFOLDS[key] = cached
    return cached[1]


def _world_box(body: SceneBody) -> np.ndarray:
    """(2, 3) world bounding box of the body's local bounding box corners (conservative)."""
    lo, hi = np.asarray(body.built.bbox, float)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    pts = transform_points(body.pose, corners)
    return np.stack([pts.min(axis=0), pts.max(axis=0)])


def _boxes_apart(a: SceneBody, b: SceneBody, margin: float) -> bool:
    """True when the bodies' oriented bounding boxes are separated by more than ``-margin``
    (separating-axis test on the 15 axes of two boxes): a cheap exact reason to skip a pair."""
    centres, halves, axes = [], [], []
    for body in (a, b):
        lo, hi = np.asarray(body.built.bbox, float)
        rot = body.pose[:3, :3]
        centres.append(body.pose[:3, :3] @ ((lo + hi) / 2) + body.pose[:3, 3])
        halves.append((hi - lo) / 2)
        axes.append(rot)
    d = centres[1] - centres[0]
    ra, rb = axes
    candidates = [ra[:, i] for i in range(3)] + [rb[:, i] for i in range(3)]
    candidates += [np.cross(ra[:, i], rb[:, j]) for i in range(3) for j in range(3)]
    for axis in candidates:
        n = np.linalg.norm(axis)
        if n < 1e-9:
            continue
        axis = axis / n
        reach = (np.abs(ra.T @ axis) @ halves[0]) + (np.abs(rb.T @ axis) @ halves[1])
        if abs(d @ axis) > reach - margin:
            return True
    return False


def _signed_distance(point: np.ndarray, piece) -> float:
    """Signed distance (m) from a point in the piece's parent frame to a primitive piece."""
    p = invert(piece.frame)[:3, :3] @ point + invert(piece.frame)[:3, 3]
    if isinstance(piece, SpherePiece):
        return float(np.linalg.norm(p) - piece.radius)
    if isinstance(piece, BoxPiece):
        q = np.abs(p) - np.asarray(piece.size, float) / 2
    else:  # CylinderPiece, axis z
        q = np.array([np.hypot(p[0], p[1]) - piece.radius, abs(p[2]) - piece.height / 2])
    return float(np.linalg.norm(np.maximum(q, 0.0)) + min(q.max(), 0.0))


_PRIMITIVES = (BoxPiece, SpherePiece, CylinderPiece)


def _ball_depth(ball: SceneBody, other: SceneBody) -> float | None:
    """Exact penetration depth of a ball into a body made of primitive pieces, or None when
    the shortcut does not apply (the ball is not a single sphere, or the other body has
    convex-hull pieces). The pieces of such parts tile their solid exactly (a track is three
    boxes), so this is the deepest a ball sinks into any of them, computed in microseconds
    where a mesh intersection with a finely tessellated ball takes milliseconds."""
    pieces = ball.built.pieces
    if len(pieces) != 1 or not isinstance(pieces[0], SpherePiece):
        return None
    if not all(isinstance(p, _PRIMITIVES) for p in other.built.pieces):
        return None
    centre = transform_points(ball.pose, pieces[0].frame[None, :3, 3])[0]
    local = transform_points(invert(other.pose), centre[None])[0]
    depth = max(pieces[0].radius - _signed_distance(local, p) for p in other.built.pieces)
    return max(depth, 0.0)


def thickness(points: np.ndarray) -> float:
    """Extent (m) of (n, 3) points along their smallest principal axis."""
    if len(points) < 4:
        return 0.0
    centred = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    proj = centred @ vt[-1]
    return float(proj.max() - proj.min())


def check_validity(scene: Scene, tolerance: float = TOLERANCE) -> Validity:
    """Test every pair of bodies that may collide; see the module docstring."""
    solids = [b for b in scene.bodies.values() if not b.plane]
    planes = [b for b in scene.bodies.values() if b.plane]
    excluded = scene.jointed_pairs()
    overlaps: list[Overlap] = []
    tested = 0

    for plane in planes:
        normal = plane.pose[:3, 2]
        origin = plane.pose[:3, 3]
        for body in solids:
            if frozenset((plane.name, body.name)) in excluded:
                continue
            box = _world_box(body)
            corners = np.array([[x, y, z] for x in box[:, 0] for y in box[:, 1] for z in box[:, 2]])
            if ((corners - origin) @ normal).min() >= -tolerance:
                continue
            tested += 1
            depth = -float(((body.world_vertices() - origin) @ normal).min())
            if depth > tolerance:
                overlaps.append(Overlap(plane.name, body.name, depth, 0.0))

    if len(solids) > 1:
        boxes = np.stack([_world_box(b) for b in solids])  # (n, 2, 3)
        lo, hi = boxes[:, 0] + tolerance / 2, boxes[:, 1] - tolerance / 2
        hits = np.all((lo[:, None, :] < hi[None, :, :]) & (lo[None, :, :] < hi[:, None, :]), axis=2)
        for i, j in zip(*np.nonzero(np.triu(hits, k=1)), strict=True):
            a, b = solids[i], solids[j]
            if frozenset((a.name, b.name)) in excluded or _boxes_apart(a, b, tolerance):
                continue
            tested += 1
            depth = _ball_depth(a, b)
            if depth is None:
                depth = _ball_depth(b, a)
            if depth is not None:
                if depth > tolerance:
                    overlaps.append(Overlap(a.name, b.name, depth, 0.0))
                continue
            inter = (_manifold(a).transform(a.pose[:3, :4])
                     ^ _manifold(b).transform(b.pose[:3, :4]))
            if inter.is_empty():
                continue
            volume = float(inter.volume())
            if volume <= 0:
                continue
            depth = thickness(np.asarray(inter.to_mesh().vert_properties)[:, :3].astype(float))
            if depth > tolerance:
                overlaps.append(Overlap(a.name, b.name, depth, volume))
    return Validity(not overlaps, tuple(overlaps), tested)
