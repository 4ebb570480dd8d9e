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


def _oriented_boxes(bodies: list[SceneBody]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World centres (n, 3), half extents (n, 3) and axes (n, 3, 3; columns) of the bodies'
    local bounding boxes."""
    lo = np.array([b.built.bbox[0] for b in bodies], float)
    hi = np.array([b.built.bbox[1] for b in bodies], float)
    rot = np.stack([b.pose[:3, :3] for b in bodies])
    centres = np.einsum("nij,nj->ni", rot, (lo + hi) / 2) + np.stack([b.pose[:3, 3] for b in bodies])
    return centres, (hi - lo) / 2, rot


def _boxes_apart(centres, halves, rot, first, second, margin: float) -> np.ndarray:
    """(p,) bool: whether the oriented boxes of each pair ``(first[k], second[k])`` are
    separated by more than ``-margin`` (separating-axis test on the 15 axes of two boxes,
    all pairs at once): a cheap exact reason to skip a pair."""
    ra, rb = rot[first], rot[second]  # (p, 3, 3), axes as columns
    axes = np.concatenate([
        ra.transpose(0, 2, 1), rb.transpose(0, 2, 1),
        np.cross(ra.transpose(0, 2, 1)[:, :, None, :], rb.transpose(0, 2, 1)[:, None, :, :])
        .reshape(-1, 9, 3),
    ], axis=1)  # (p, 15, 3)
    norm = np.linalg.norm(axes, axis=2)
    usable = norm > 1e-9
    axes = axes / np.where(usable, norm, 1.0)[..., None]
    reach = (np.abs(np.einsum("pkj,pji->pki", axes, ra)) @ halves[first][..., None])[..., 0] + (
        np.abs(np.einsum("pkj,pji->pki", axes, rb)) @ halves[second][..., None])[..., 0]
    gap = np.abs(np.einsum("pkj,pj->pk", axes, centres[second] - centres[first]))
    return np.any(usable & (gap > reach - margin), axis=1)


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


def check_validity(
    scene: Scene, tolerance: float = TOLERANCE, stop_at_first: bool = False
) -> Validity:
    """Test every pair of bodies that may collide; see the module docstring.

    With ``stop_at_first`` the test returns at the first penetration found (``overlaps``
    then holds that one): enough for a yes/no answer, and most random layouts of a crowded
    scene are invalid.
    """
    solids = [b for b in scene.bodies.values() if not b.plane]
    planes = [b for b in scene.bodies.values() if b.plane]
    excluded = scene.jointed_pairs()
    overlaps: list[Overlap] = []
    tested = 0
    if not solids:
        return Validity(True, (), 0)
    centres, halves, rot = _oriented_boxes(solids)

    for plane in planes:
        normal = plane.pose[:3, 2]
        origin = plane.pose[:3, 3]
        # lowest point of each oriented box along the plane's normal
        lowest = (centres - origin) @ normal - np.einsum(
            "ni,ni->n", np.abs(np.einsum("nji,j->ni", rot, normal)), halves
        )
        for k in np.flatnonzero(lowest < -tolerance):
            body = solids[k]
            if frozenset((plane.name, body.name)) in excluded:
                continue
            tested += 1
            depth = -float(((body.world_vertices() - origin) @ normal).min())
            if depth > tolerance:
                overlaps.append(Overlap(plane.name, body.name, depth, 0.0))
                if stop_at_first:
                    return Validity(False, tuple(overlaps), tested)

    if len(solids) > 1:
        reach = np.abs(rot) @ halves[..., None]  # (n, 3, 1): half extents of the world box
        lo = centres - reach[..., 0] + tolerance / 2
        hi = centres + reach[..., 0] - tolerance / 2
        hits = np.all((lo[:, None, :] < hi[None, :, :]) & (lo[None, :, :] < hi[:, None, :]), axis=2)
        pairs = [(i, j) for i, j in zip(*np.nonzero(np.triu(hits, k=1)), strict=True)
                 if frozenset((solids[i].name, solids[j].name)) not in excluded]
        if pairs:
            first, second = np.array(pairs).T
            apart = _boxes_apart(centres, halves, rot, first, second, tolerance)
            pairs = [p for p, skip in zip(pairs, apart, strict=True) if not skip]
        for i, j in pairs:
            a, b = solids[i], solids[j]
            tested += 1
            depth = _ball_depth(a, b)
            if depth is None:
                depth = _ball_depth(b, a)
            if depth is not None:
                if depth > tolerance:
                    overlaps.append(Overlap(a.name, b.name, depth, 0.0))
                    if stop_at_first:
                        break
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
                if stop_at_first:
                    break
    return Validity(not overlaps, tuple(overlaps), tested)
