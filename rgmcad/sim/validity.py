"""Physical validity of a layout: do any two bodies intersect at the start?

Exact, on the parts' CAD meshes: every pair of distinct bodies that may collide (static pairs
included, jointed pairs excluded) whose bounding boxes overlap is intersected with manifold3d.
An intersection counts as a penetration of depth ``t``, the thickness of the intersection solid
along its thinnest direction (its smallest principal axis): exact for the slab two flat faces
make and for the cap a ball sinks into a plane. A body against an infinite plane is tested
exactly by the signed distances of its vertices, and a ball against a part made of box, sphere
and cylinder pieces (which tile it exactly) by the distances of its centre to those pieces.

:class:`~rgmcad.sim.layout_validity.LayoutValidity` gives the same yes/no answers for
thousands of layouts at once (the samplers' case), with the poses, the box tests, the ball
shortcut and a sufficient test for bodies made of boxes (two shrunk boxes that intersect)
vectorised over layouts.

The layout is valid when no penetration is deeper than ``tolerance`` (default 0.2 mm): bodies
that touch are valid, a 0.5 mm overlap is not. The paper summed Bullet's contact depths against
1 mm, which let thin parts overlap by most of their thickness.

The work is bounded before it starts: past MAX_EXACT_PAIRS pairs whose boxes overlap (two runs
of wide dominoes crossing each other make up to a million), the test stops at its
ENOUGH_OVERLAPS-th penetration (one decides the verdict) and counts the pairs it left
untested; below it, every penetration is listed, as a hand placing parts again needs.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import manifold3d
import numpy as np

from rgmcad.geometry import invert, matmul, principal_axes, transform_points
from rgmcad.parts.pieces import SpherePiece
from rgmcad.parts.store import BuiltBody
from rgmcad.scene.bodies import Scene, SceneBody
from rgmcad.sim.cache import PartCache
from rgmcad.sim.distances import _PRIMITIVES, _signed_distance
from rgmcad.sim.rope_validity import RopePath, rope_crossings

TOLERANCE = 2e-4
"""Deepest penetration (m) still counted as touching."""
MAX_EXACT_PAIRS = 1000
"""Pairs whose boxes overlap past which the test stops at ENOUGH_OVERLAPS penetrations (the
shipped scenarios have at most 23, long_chain's, in their layouts and 200 random ones each)."""
ENOUGH_OVERLAPS = 20
SHOWN = 5
"""Penetrations a report lists (the deepest; :meth:`Validity.shown`)."""
_CHUNK = 4096  # pairs per separating-axis test: bounded memory (15 axes x 3 floats each)


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
    untested: int = 0  # pairs whose boxes overlap left once the verdict was known (stop_at_first,
    # or ENOUGH_OVERLAPS found among more than MAX_EXACT_PAIRS)

    @property
    def penetration(self) -> float:
        """Sum of the penetration depths beyond the tolerance (m); 0 for a valid layout."""
        return float(sum(o.depth for o in self.overlaps))

    def shown(self, count: int = SHOWN) -> tuple[tuple[Overlap, ...], str | None]:
        """What a report lists: every penetration when there are at most ``count`` (in the
        order found), else the ``count`` deepest; and a line for the rest (None: nothing
        left out), e.g. ``"and 15 more pairs overlap; 89,980 more pairs whose boxes overlap
        were not tested"``."""
        if len(self.overlaps) <= count and not self.untested:
            return self.overlaps, None
        shown = tuple(sorted(self.overlaps, key=lambda o: -o.depth)[:count])
        more = [f"and {len(self.overlaps) - len(shown):,} more pairs overlap"] * (
            len(self.overlaps) > len(shown))
        more += [f"{self.untested:,} more pairs whose boxes overlap were not tested"] * bool(
            self.untested)
        return shown, "; ".join(more)


def _manifold(built: BuiltBody, cache: PartCache) -> manifold3d.Manifold:
    """The body's mesh as a Manifold, built once per cache and per built body."""
    def make():
        return manifold3d.Manifold(manifold3d.Mesh(
            vert_properties=np.asarray(built.vertices, np.float32),
            tri_verts=np.asarray(built.faces, np.uint32)))

    return cache.get("manifold", built, make)


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
    ta, tb = ra.transpose(0, 2, 1), rb.transpose(0, 2, 1)
    axes = np.concatenate([ta, tb, _cross(ta[:, :, None, :], tb[:, None, :, :]).reshape(-1, 9, 3)],
                          axis=1)  # (p, 15, 3)
    norm = np.linalg.norm(axes, axis=2)
    usable = norm > 1e-9
    axes = axes / np.where(usable, norm, 1.0)[..., None]
    reach = (matmul(np.abs(matmul(axes, ra)), halves[first][..., None])
             + matmul(np.abs(matmul(axes, rb)), halves[second][..., None]))[..., 0]
    gap = np.abs(np.einsum("pkj,pj->pk", axes, centres[second] - centres[first]))
    return np.any(usable & (gap > reach - margin), axis=1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` over the last axis (3), broadcast; the same products and differences
    without its axis juggling, which cost more than the arithmetic on small arrays."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _ball_depth(ball: BuiltBody, ball_pose, other: BuiltBody, other_pose) -> float | None:
    """Exact penetration depth of a ball into a body made of primitive pieces, or None when
    the shortcut does not apply (the ball is not a single sphere, or the other body has
    convex-hull pieces). The pieces of such parts tile their solid exactly (a track is three
    boxes), so this is the deepest a ball sinks into any of them, computed in microseconds
    where a mesh intersection with a finely tessellated ball takes milliseconds."""
    pieces = ball.pieces
    if not _is_ball(ball):
        return None
    if not all(isinstance(p, _PRIMITIVES) for p in other.pieces):
        return None
    centre = transform_points(ball_pose, pieces[0].frame[None, :3, 3])[0]
    local = transform_points(invert(other_pose), centre[None])[0]
    depth = max(pieces[0].radius - _signed_distance(local, p) for p in other.pieces)
    return max(depth, 0.0)


def _is_ball(built: BuiltBody) -> bool:
    return len(built.pieces) == 1 and isinstance(built.pieces[0], SpherePiece)


def _pair_penetration(a: BuiltBody, pose_a, b: BuiltBody, pose_b,
                      cache: PartCache) -> tuple[float, float]:
    """``(depth, volume)`` of the intersection of two posed bodies (m, m^3; ``(0, 0)`` when
    they do not intersect; volume 0 when a ball was tested analytically)."""
    depth = _ball_depth(a, pose_a, b, pose_b)
    if depth is None:
        depth = _ball_depth(b, pose_b, a, pose_a)
    if depth is not None:
        return depth, 0.0
    inter = _manifold(a, cache) ^ _manifold(b, cache).transform(
        matmul(invert(pose_a), pose_b)[:3, :4])  # in a's frame
    if inter.is_empty():
        return 0.0, 0.0
    volume = float(inter.volume())
    if volume <= 0:
        return 0.0, 0.0
    return thickness(np.asarray(inter.to_mesh().vert_properties)[:, :3].astype(float)), volume


def _plane_depth(body: BuiltBody, pose, origin, normal) -> float:
    """How far (m) a posed body reaches below a plane (negative when it stays above)."""
    return -float(matmul(transform_points(pose, body.vertices) - origin, normal).min())


def thickness(points: np.ndarray) -> float:
    """Extent (m) of (n, 3) points along their smallest principal axis."""
    if len(points) < 4:
        return 0.0
    centred = points - points.mean(axis=0)
    _, axes = principal_axes(matmul(centred.T, centred))
    proj = matmul(centred, axes[:, 0])
    return float(proj.max() - proj.min())


def _box_pairs(solids, centres, halves, rot, excluded, tolerance) -> tuple[np.ndarray, np.ndarray]:
    """``(first, second)``: the pairs ``i < j`` of solids that may collide (not jointed) whose
    world-aligned boxes overlap by more than ``tolerance``, row by row."""
    reach = matmul(np.abs(rot), halves[..., None])  # (n, 3, 1): half extents of the world box
    lo = centres - reach[..., 0] + tolerance / 2
    hi = centres + reach[..., 0] - tolerance / 2
    hits = np.all((lo[:, None, :] < hi[None, :, :]) & (lo[None, :, :] < hi[:, None, :]), axis=2)
    index = {b.name: k for k, b in enumerate(solids)}
    for pair in excluded:
        ks = [index[name] for name in pair if name in index]
        if len(ks) == 2:
            hits[ks[0], ks[1]] = hits[ks[1], ks[0]] = False
    return np.nonzero(np.triu(hits, k=1))


def _apart_pruned(centres, halves, rot, first, second, tolerance) -> Iterator[int]:
    """The positions in ``(first, second)`` of the pairs whose oriented boxes overlap, in
    order, tested _CHUNK pairs at a time as they are asked for."""
    for start in range(0, len(first), _CHUNK):
        end = start + _CHUNK
        apart = _boxes_apart(centres, halves, rot, first[start:end], second[start:end], tolerance)
        yield from (start + np.flatnonzero(~apart)).tolist()


def check_validity(
    scene: Scene, tolerance: float = TOLERANCE, stop_at_first: bool = False,
    cache: PartCache | None = None,
) -> Validity:
    """Test every pair of bodies that may collide; see the module docstring.

    With ``stop_at_first`` the test returns at the first penetration found (``overlaps``
    then holds that one): enough for a yes/no answer, and most random layouts of a crowded
    scene are invalid. ``cache`` keeps the parts' meshes for the next call.
    """
    cache = PartCache() if cache is None else cache
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
        lowest = matmul(centres - origin, normal) - np.einsum(
            "ni,ni->n", np.abs(np.einsum("nji,j->ni", rot, normal)), halves
        )
        for k in np.flatnonzero(lowest < -tolerance):
            body = solids[k]
            if frozenset((plane.name, body.name)) in excluded:
                continue
            tested += 1
            depth = _plane_depth(body.built, body.pose, origin, normal)
            if depth > tolerance:
                overlaps.append(Overlap(plane.name, body.name, depth, 0.0))
                if stop_at_first:
                    return Validity(False, tuple(overlaps), tested)

    untested = 0
    if len(solids) > 1:
        first, second = _box_pairs(solids, centres, halves, rot, excluded, tolerance)
        enough = ENOUGH_OVERLAPS if len(first) > MAX_EXACT_PAIRS else None
        for at in _apart_pruned(centres, halves, rot, first, second, tolerance):
            a, b = solids[first[at]], solids[second[at]]
            tested += 1
            depth, volume = _pair_penetration(a.built, a.pose, b.built, b.pose, cache)
            if depth > tolerance:
                overlaps.append(Overlap(a.name, b.name, depth, volume))
                if stop_at_first or (enough is not None and len(overlaps) >= enough):
                    untested = len(first) - at - 1
                    break
    overlaps.extend(Overlap(f"rope {r.name} (too short)", "its path", r.excess, 0.0)
                    for r in scene.ropes if r.excess > tolerance)  # depth: missing length
    if scene.ropes and not ((stop_at_first or untested) and overlaps):
        bodies = list(scene.bodies.values())
        overlaps.extend(Overlap(f"rope {c.rope} (through {c.body})", c.body, c.depth, 0.0)
                        for c in rope_crossings(
                            bodies, np.stack([b.pose for b in bodies])[None],
                            [RopePath(r.name, r.objects, r.points[None]) for r in scene.ropes],
                            tolerance, cache))
    return Validity(not overlaps, tuple(overlaps), tested, untested)
