"""Ropes that pass through a body at the start of a layout (part of its validity).

A rope is straight segments between the points of its path (its two hooks and its pulley
points). A segment penetrates a body when some point of it lies deeper than the tolerance
inside the body's solid: its exact CAD mesh (distances to its triangles, inside by the
winding number), a ball's sphere, an infinite plane's half-space. The mesh and not the
collision pieces: a rope in the plane where two pieces meet (a goblet's wall sectors, a
track's wall on its base) is inside the solid but on the surface of each piece.

The deepest point of a segment is found by branch and bound: the signed distance is
1-Lipschitz, so an interval whose ends lie at distances ``s0``, ``s1`` reaches at most
``(l - s0 - s1) / 2`` deep; intervals that might reach deeper than the tolerance (or than the
deepest point found) are halved until none can: decided to a micrometre, the depth reported
to 10 micrometres.

A segment is not tested against the objects its two points belong to: the object named at
that point, and any object with a body the point lies in or on (within the tolerance), such
as the pulley (wheel and axle) whose rim a pulley point sits on, or the part whose surface a
hook is screwed to.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rgmcad.geometry import matmul
from rgmcad.parts.pieces import SpherePiece
from rgmcad.parts.store import BuiltBody
from rgmcad.sim.cache import PartCache

RESOLUTION = 1e-6
"""How close (m) to the tolerance a segment's deepest point may lie undecided."""
DEPTH_RESOLUTION = 1e-5
"""How close (m) a reported depth is to the true deepest point's."""
_SAMPLES_PER_METRE = 1000  # first samples along a segment, before any halving
_MAX_POINTS = 20_000  # of one segment against one body: a rope lying at the tolerance's depth


@dataclass(frozen=True)
class RopePath:
    """One rope's path in m layouts: ``points`` (m, k, 3) world points and the object each
    point is tied to or runs over (None: the world)."""

    name: str
    objects: tuple[str | None, ...]
    points: np.ndarray


@dataclass(frozen=True)
class Crossing:
    row: int  # which layout
    rope: str
    body: str
    depth: float  # m, of the rope's deepest point inside the body


def _mesh_distance(mesh: dict, points: np.ndarray) -> np.ndarray:
    """(p,) signed distance (m, negative inside) from points (p, 3) to the closed surface of a
    :func:`_triangles` mesh: the nearest triangle's distance; inside where the generalised
    winding number (the triangles' solid angles seen from the point over 4 pi) exceeds one
    half."""
    a, b, c = mesh["a"], mesh["b"], mesh["c"]
    ab, ac, bc, normal, area2 = mesh["ab"], mesh["ac"], mesh["bc"], mesh["normal"], mesh["area2"]
    d00, d01, d11, denom = mesh["d00"], mesh["d01"], mesh["d11"], mesh["denom"]
    out = np.empty(len(points))
    chunk = max(1, 250_000 // len(a))
    for start in range(0, len(points), chunk):
        p = points[start:start + chunk, None, :]  # (q, 1, 3)
        ap = p - a
        dist = np.minimum(np.minimum(_to_segment(ap, ab), _to_segment(p - b, bc)),
                          _to_segment(ap, ac))
        d20, d21 = np.einsum("qtj,tj->qt", ap, ab), np.einsum("qtj,tj->qt", ap, ac)
        v, w = (d11 * d20 - d01 * d21) / denom, (d00 * d21 - d01 * d20) / denom
        height = np.einsum("qtj,tj->qt", ap, normal)  # the foot on the plane is inside:
        dist = np.where((v >= 0) & (w >= 0) & (v + w <= 1), np.minimum(dist, np.abs(height)),
                        dist).min(axis=1)
        ra, rb, rc = a - p, b - p, c - p
        la, lb, lc = (np.sqrt(np.einsum("qtj,qtj->qt", r, r)) for r in (ra, rb, rc))
        det = -height * area2  # ra . (rb x rc), the tetrahedron's signed volume x 6
        den = (la * lb * lc + np.einsum("qtj,qtj->qt", ra, rb) * lc
               + np.einsum("qtj,qtj->qt", ra, rc) * lb + np.einsum("qtj,qtj->qt", rb, rc) * la)
        winding = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
        out[start:start + chunk] = np.where(np.abs(winding) > 0.5, -dist, dist)
    return out


def _triangles(built: BuiltBody) -> dict:
    """A body's mesh triangles (corners, edges, unit normals, twice the areas) and the dot
    products of their edges, computed once per part."""
    tri = np.asarray(built.vertices, float)[np.asarray(built.faces)]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac = b - a, c - a
    cross = np.cross(ab, ac)
    area2 = np.linalg.norm(cross, axis=1)
    keep = area2 > 1e-18  # degenerate triangles add nothing to either sum
    d00, d01, d11 = (np.einsum("tj,tj->t", x, y) for x, y in ((ab, ab), (ab, ac), (ac, ac)))
    mesh = {"a": a, "b": b, "c": c, "ab": ab, "ac": ac, "bc": c - b,
            "normal": cross / np.where(keep, area2, 1.0)[:, None], "area2": area2,
            "d00": d00, "d01": d01, "d11": d11, "denom": d00 * d11 - d01 * d01}
    return {k: v[keep] for k, v in mesh.items()}


def _to_segment(ap: np.ndarray, ab: np.ndarray) -> np.ndarray:
    """Distances from points ``a + ap`` (q, t, 3) to segments a -> a + ab (t, 3)."""
    t = np.clip(np.einsum("qtj,tj->qt", ap, ab) / np.einsum("tj,tj->t", ab, ab), 0.0, 1.0)
    return np.linalg.norm(ap - t[..., None] * ab, axis=2)


def _signed_distance(built: BuiltBody, cache: PartCache) -> Callable[[np.ndarray], np.ndarray]:
    """Signed distance (m, negative inside) to a body, for points (p, 3) in its part frame."""
    pieces = built.pieces
    if len(pieces) == 1 and isinstance(pieces[0], SpherePiece):
        centre, radius = np.asarray(pieces[0].frame, float)[:3, 3], pieces[0].radius
        return lambda points: np.linalg.norm(points - centre, axis=1) - radius
    mesh = cache.get("rope triangles", built, lambda: _triangles(built))
    return lambda points: _mesh_distance(mesh, points)


def _deepest(distance, a: np.ndarray, b: np.ndarray, tolerance: float,
             exact: bool = True) -> float:
    """Depth (m, > tolerance) of the deepest point of segment a -> b (3,) under the signed
    ``distance``, or 0 when no point lies deeper than ``tolerance`` (branch and bound); not
    ``exact``: the depth of the first point found deeper than ``tolerance``."""
    length = float(np.linalg.norm(b - a))
    ts = np.linspace(0.0, 1.0, int(np.clip(length * _SAMPLES_PER_METRE, 1, 128)) + 1)
    sd = distance(a + ts[:, None] * (b - a))
    while len(ts) < _MAX_POINTS:
        best = float(-sd.min())
        if best > tolerance and not exact:
            break
        bound = (np.diff(ts) * length - sd[:-1] - sd[1:]) / 2
        open_ = np.flatnonzero(bound > (best + DEPTH_RESOLUTION if best > tolerance
                                         else tolerance + RESOLUTION))
        if len(open_) == 0:
            break
        mid = (ts[open_] + ts[open_ + 1]) / 2
        ts = np.insert(ts, open_ + 1, mid)
        sd = np.insert(sd, open_ + 1, distance(a + mid[:, None] * (b - a)))
    best = float(-sd.min())
    return best if best > tolerance else 0.0


def _clip_to_box(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """The part of segment a -> b (3,) inside the box [lo, hi] (3,), or None (slab test)."""
    d = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        t0, t1 = (lo - a) / d, (hi - a) / d
    flat = d == 0
    if np.any(flat & ((a < lo) | (a > hi))):
        return None
    enter = np.where(flat, 0.0, np.minimum(t0, t1)).max(initial=0.0)
    leave = np.where(flat, 1.0, np.maximum(t0, t1)).min(initial=1.0)
    return None if enter > leave else (a + enter * d, a + leave * d)


def rope_crossings(bodies: Sequence, poses: np.ndarray, ropes: Sequence[RopePath],
                   tolerance: float, cache: PartCache, rows: np.ndarray | None = None,
                   exact: bool = True) -> list[Crossing]:
    """Every (layout, rope, body) where a segment of a rope lies deeper than ``tolerance``
    inside a body it does not belong to; ``bodies`` are scene bodies (``name``, ``object``,
    ``built``; None: an infinite plane, the +Z side of its pose) posed at ``poses``
    (m, n, 4, 4); ``rows`` limits the test to those layouts. Not ``exact``: the same
    crossings, each with the depth of a point deeper than ``tolerance``, not the deepest."""
    rows = np.arange(poses.shape[0]) if rows is None else np.asarray(rows, int)
    siblings: dict[str, list[int]] = {}
    for i, body in enumerate(bodies):
        siblings.setdefault(body.object, []).append(i)

    def local(row, i, point):
        pose = poses[row, i]
        return matmul(pose[:3, :3].T, point - pose[:3, 3])

    def distance(row, i, point):
        if bodies[i].built is None:
            return float(local(row, i, point)[2])
        return float(_signed_distance(bodies[i].built, cache)(local(row, i, point)[None])[0])

    lo, hi = _world_boxes(bodies, poses[rows])
    out = []
    for rope in ropes:
        for k in range(len(rope.objects) - 1):
            ends = {rope.objects[k], rope.objects[k + 1]} - {None}
            a, b = rope.points[rows, k], rope.points[rows, k + 1]
            near = np.all((np.minimum(a, b)[:, None] + tolerance < hi)
                          & (lo < np.maximum(a, b)[:, None] - tolerance), axis=2)  # (r, n)
            for r, i in zip(*np.nonzero(near), strict=True):
                body, row = bodies[i], rows[r]
                if body.object in ends:
                    continue
                la, lb = local(row, i, a[r]), local(row, i, b[r])
                depth = _segment_depth(body.built, la, lb, tolerance, cache, exact=False)
                if depth > tolerance and all(
                        distance(row, j, p) > tolerance
                        for j in siblings[body.object] for p in (a[r], b[r])):
                    if exact:  # the deepest point, which the first one found need not be
                        depth = _segment_depth(body.built, la, lb, tolerance, cache)
                    out.append(Crossing(int(row), rope.name, body.name, depth))
    return sorted(out, key=lambda c: c.row)


def _world_boxes(bodies: Sequence, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World bounding boxes (r, n, 3) low and high of the bodies' part boxes, posed at
    ``poses`` (r, n, 4, 4); a plane's is everything."""
    lo, hi = np.full(poses.shape[:2] + (3,), -np.inf), np.full(poses.shape[:2] + (3,), np.inf)
    solid = [i for i, b in enumerate(bodies) if b.built is not None]
    if solid:
        box_lo = np.array([bodies[i].built.bbox[0] for i in solid], float)
        box_hi = np.array([bodies[i].built.bbox[1] for i in solid], float)
        posed = poses[:, solid]
        centres = np.einsum("rnij,nj->rni", posed[..., :3, :3], (box_lo + box_hi) / 2) + \
            posed[..., :3, 3]
        reach = np.einsum("rnij,nj->rni", np.abs(posed[..., :3, :3]), (box_hi - box_lo) / 2)
        lo[:, solid], hi[:, solid] = centres - reach, centres + reach
    return lo, hi


def _segment_depth(built: BuiltBody | None, a: np.ndarray, b: np.ndarray, tolerance: float,
                   cache: PartCache, exact: bool = True) -> float:
    """Deepest (m) the segment a -> b (3, in the body's part frame) reaches inside the body,
    or 0 when it stays within ``tolerance`` of its outside."""
    if built is None:  # the half-space z <= 0: deepest at an end
        return max(0.0, -float(min(a[2], b[2]))) if min(a[2], b[2]) < -tolerance else 0.0
    lo, hi = np.asarray(built.bbox[0], float), np.asarray(built.bbox[1], float)
    clipped = _clip_to_box(a, b, lo + tolerance, hi - tolerance)
    if clipped is None:
        return 0.0
    return _deepest(_signed_distance(built, cache), *clipped, tolerance, exact)
