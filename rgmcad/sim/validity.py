"""Physical validity of a layout: do any two bodies intersect at the start?

Exact, on the parts' CAD meshes: every pair of distinct bodies that may collide (static pairs
included, jointed pairs excluded) whose bounding boxes overlap is intersected with manifold3d.
An intersection counts as a penetration of depth ``t``, the thickness of the intersection solid
along its thinnest direction (its smallest principal axis): exact for the slab two flat faces
make and for the cap a ball sinks into a plane. A body against an infinite plane is tested
exactly by the signed distances of its vertices, and a ball against a part made of box, sphere
and cylinder pieces (which tile it exactly) by the distances of its centre to those pieces.

:class:`LayoutValidity` gives the same yes/no answers for thousands of layouts at once (the
samplers' case), with the poses, the box tests, the ball shortcut and a sufficient test for
bodies made of boxes (two shrunk boxes that intersect) vectorised over layouts.

The layout is valid when no penetration is deeper than ``tolerance`` (default 0.2 mm): bodies
that touch are valid, a 0.5 mm overlap is not. The paper summed Bullet's contact depths against
1 mm, which let thin parts overlap by most of their thickness.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import singledispatch

import manifold3d
import numpy as np

from rgmcad.geometry import invert, transform_points
from rgmcad.parts.pieces import BoxPiece, CapsulePiece, CylinderPiece, SpherePiece
from rgmcad.parts.store import BuiltBody
from rgmcad.scene.bodies import Scene, SceneBody
from rgmcad.scene.ropes import ropes_fit_many
from rgmcad.sim.cache import PartCache

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


@singledispatch
def signed_distances(piece, points: np.ndarray) -> np.ndarray:
    """(m,) signed distances (m) from points (m, 3), given in the piece's own frame, to a
    primitive piece (a box, sphere or cylinder)."""
    raise TypeError(f"no signed distance to a {type(piece).__name__}")


@signed_distances.register
def _(piece: SpherePiece, points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points, axis=-1) - piece.radius


@signed_distances.register
def _(piece: BoxPiece, points: np.ndarray) -> np.ndarray:
    return _box_distance(np.abs(points) - np.asarray(piece.size, float) / 2)


@signed_distances.register
def _(piece: CylinderPiece, points: np.ndarray) -> np.ndarray:  # axis z
    return _box_distance(np.stack([np.hypot(points[:, 0], points[:, 1]) - piece.radius,
                                   np.abs(points[:, 2]) - piece.height / 2], axis=1))


@signed_distances.register
def _(piece: CapsulePiece, points: np.ndarray) -> np.ndarray:  # axis z
    along = np.clip(points[:, 2], -piece.length / 2, piece.length / 2)
    return np.linalg.norm(points - np.outer(along, [0, 0, 1]), axis=1) - piece.radius


def _box_distance(q: np.ndarray) -> np.ndarray:
    """Signed distances from per-axis excesses (m, k) over a box's half sizes."""
    return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)


def _signed_distance(point: np.ndarray, piece) -> float:
    """Signed distance (m) from a point in the piece's parent frame to a primitive piece."""
    return float(signed_distances(piece, transform_points(invert(piece.frame), point[None]))[0])


_PRIMITIVES = tuple(t for t in signed_distances.registry if t is not object)
"""Piece types that tile a part exactly and have a signed distance."""


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
        (invert(pose_a) @ pose_b)[:3, :4])  # in a's frame
    if inter.is_empty():
        return 0.0, 0.0
    volume = float(inter.volume())
    if volume <= 0:
        return 0.0, 0.0
    return thickness(np.asarray(inter.to_mesh().vert_properties)[:, :3].astype(float)), volume


def _plane_depth(body: BuiltBody, pose, origin, normal) -> float:
    """How far (m) a posed body reaches below a plane (negative when it stays above)."""
    return -float(((transform_points(pose, body.vertices) - origin) @ normal).min())


def thickness(points: np.ndarray) -> float:
    """Extent (m) of (n, 3) points along their smallest principal axis."""
    if len(points) < 4:
        return 0.0
    centred = points - points.mean(axis=0)
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    proj = centred @ vt[-1]
    return float(proj.max() - proj.min())


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
        lowest = (centres - origin) @ normal - np.einsum(
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
            depth, volume = _pair_penetration(a.built, a.pose, b.built, b.pose, cache)
            if depth > tolerance:
                overlaps.append(Overlap(a.name, b.name, depth, volume))
                if stop_at_first:
                    break
    overlaps.extend(Overlap(f"rope {r.name} (too short)", "its path", r.excess, 0.0)
                    for r in scene.ropes if r.excess > tolerance)  # depth: missing length
    return Validity(not overlaps, tuple(overlaps), tested)


def _box_pieces(built: BuiltBody, cache: PartCache) -> tuple[np.ndarray, np.ndarray] | None:
    """Frames (p, 4, 4) and half sizes (p, 3) of a body made only of box pieces that all lie
    inside its mesh (checked with manifold3d), else None: then a ball inside one of its
    pieces is inside the body."""
    if not built.pieces or not all(isinstance(q, BoxPiece) for q in built.pieces):
        return None
    boxes = manifold3d.Manifold.batch_boolean(
        [manifold3d.Manifold.cube(tuple(q.size), True).transform(np.asarray(q.frame)[:3, :4])
         for q in built.pieces], manifold3d.OpType.Add)
    outside = float((boxes - _manifold(built, cache)).volume())
    if outside > 1e-6 * float(boxes.volume()):  # float32 mesh: ~1e-9 relative
        return None
    return (np.stack([np.asarray(q.frame, float) for q in built.pieces]),
            np.array([q.size for q in built.pieces], float) / 2)


def _boxes_share_a_deep_point(frames_a, halves_a, frames_b, halves_b, depth: float) -> np.ndarray:
    """(p,) bool: whether some point lies at least ``depth`` inside both boxes of each pair
    (world frames (p, 4, 4), half sizes (p, 3)): the boxes shrunk by ``depth`` on every side
    intersect, which the separating-axis test decides exactly."""
    inner_a, inner_b = halves_a - depth, halves_b - depth
    p = len(frames_a)
    rows = np.arange(p)
    centres = np.concatenate([frames_a[:, :3, 3], frames_b[:, :3, 3]])
    halves = np.concatenate([np.maximum(inner_a, 0.0), np.maximum(inner_b, 0.0)])
    rot = np.concatenate([frames_a[:, :3, :3], frames_b[:, :3, :3]])
    overlap = ~_boxes_apart(centres, halves, rot, rows, p + rows, margin=0.0)
    return overlap & np.all(inner_a > 0, axis=1) & np.all(inner_b > 0, axis=1)


class LayoutValidity:
    """Yes/no validity of many layouts of one scenario at once: for every row of real
    parameter values, the answer of ``check_validity(make_scene(scenario, values, parts),
    tolerance).valid``, computed with the same tests in the same terms. The poses, the plane
    bounds and the box pruning are vectorised over layouts; only the pairs whose oriented boxes
    overlap get an exact test, and a layout's tests stop at its first penetration. A sampler
    tests thousands of random layouts per run, most of them invalid: this is several times
    faster than one scene at a time (figures in docs/decisions.md).

    Parameters
    ----------
    scenario : Scenario
    parts : Mapping[str, BuiltPart]
        The scenario's built parts.
    tolerance : float
        As in :func:`check_validity`.
    cache : PartCache, optional
        Keeps the parts' meshes (shared with :func:`check_validity` calls given it).
    """

    def __init__(self, scenario, parts, tolerance: float = TOLERANCE,
                 cache: PartCache | None = None):
        from rgmcad.scene.bodies import make_scene
        from rgmcad.scene.design_space import bounds

        low, high = bounds(scenario)
        scene = make_scene(scenario, (low + high) / 2, parts)  # any layout: same bodies
        excluded = scene.jointed_pairs()
        self.scenario = scenario
        self.tolerance = float(tolerance)
        self.cache = PartCache() if cache is None else cache
        self.solids = [b for b in scene.bodies.values() if not b.plane]
        self.planes = [b for b in scene.bodies.values() if b.plane]
        lo = np.array([b.built.bbox[0] for b in self.solids], float).reshape(-1, 3)
        hi = np.array([b.built.bbox[1] for b in self.solids], float).reshape(-1, 3)
        self.local_centres, self.halves = (lo + hi) / 2, (hi - lo) / 2
        n = len(self.solids)
        pairs = [(i, j) for i in range(n) for j in range(i + 1, n)
                 if frozenset((self.solids[i].name, self.solids[j].name)) not in excluded]
        # cheapest exact tests first (any order gives the same answer): balls are analytic,
        # then fewest triangles
        size = [0 if _is_ball(b.built) else len(b.built.faces) for b in self.solids]
        pairs.sort(key=lambda ij: min(size[ij[0]], size[ij[1]]) + size[ij[0]] + size[ij[1]])
        self.pairs = np.array(pairs, dtype=int).reshape(-1, 2)
        # Pairs decided without a mesh intersection (same answers, vectorised over layouts):
        # a ball against primitive pieces gets its exact depth (as in _ball_depth); two bodies
        # made of boxes penetrate when some point lies more than tolerance / 2 deep inside a
        # box of each: the intersection then holds a ball of diameter > tolerance, so it is
        # thicker than that in every direction. Only the pairs without such a point go on to
        # manifold3d, the costly test.
        boxes = [_box_pieces(b.built, self.cache) for b in self.solids]
        primitive = [all(isinstance(q, _PRIMITIVES) for q in b.built.pieces) for b in self.solids]
        self.shortcuts: list[tuple | None] = []
        for i, j in pairs:
            if _is_ball(self.solids[i].built) and primitive[j]:
                self.shortcuts.append(("ball", i, j))
            elif _is_ball(self.solids[j].built) and primitive[i]:
                self.shortcuts.append(("ball", j, i))
            elif boxes[i] is not None and boxes[j] is not None:
                self.shortcuts.append(("boxes", boxes[i], boxes[j]))
            else:
                self.shortcuts.append(None)
        self.plane_solids = [
            np.array([frozenset((p.name, b.name)) not in excluded for b in self.solids])
            for p in self.planes
        ]

    def __call__(self, values) -> np.ndarray:
        """(m,) bool for real parameter values (m, d)."""
        from rgmcad.scene.design_space import world_poses_many

        values = np.atleast_2d(np.asarray(values, float))
        m, n, tol = len(values), len(self.solids), self.tolerance
        valid = np.ones(m, dtype=bool)
        if n == 0 or m == 0:
            return valid
        world = world_poses_many(self.scenario, values)
        valid &= ropes_fit_many(self.scenario, world, tol)  # ropes long enough for their path
        poses = np.stack([world[b.object] for b in self.solids], axis=1)  # (m, n, 4, 4)
        rot = poses[..., :3, :3]
        centres = np.einsum("mnij,nj->mni", rot, self.local_centres) + poses[..., :3, 3]

        for plane, allowed in zip(self.planes, self.plane_solids, strict=True):
            plane_pose = world[plane.object]
            normal, origin = plane_pose[:, :3, 2], plane_pose[:, :3, 3]
            lowest = np.einsum("mni,mi->mn", centres - origin[:, None], normal) - np.einsum(
                "mni,ni->mn", np.abs(np.einsum("mnji,mj->mni", rot, normal)), self.halves)
            for row, k in zip(*np.nonzero((lowest < -tol) & allowed), strict=True):
                if valid[row] and _plane_depth(self.solids[k].built, poses[row, k],
                                               origin[row], normal[row]) > tol:
                    valid[row] = False

        if len(self.pairs) == 0:
            return valid
        first, second = self.pairs.T
        reach = np.einsum("mnij,nj->mni", np.abs(rot), self.halves)
        lo, hi = centres - reach + tol / 2, centres + reach - tol / 2
        hits = np.all((lo[:, first] < hi[:, second]) & (lo[:, second] < hi[:, first]), axis=2)
        rows, ks = np.nonzero(hits & valid[:, None])  # layout by layout, pairs in order
        if len(rows) == 0:
            return valid
        apart = _boxes_apart(centres.reshape(-1, 3), np.tile(self.halves, (m, 1)),
                             rot.reshape(-1, 3, 3), rows * n + first[ks], rows * n + second[ks],
                             tol)
        rows, ks = rows[~apart], ks[~apart]
        exact = np.ones(len(rows), dtype=bool)
        for k in np.unique(ks):
            if self.shortcuts[k] is None:
                continue
            at = np.flatnonzero(ks == k)
            kind, *args = self.shortcuts[k]
            if kind == "ball":  # args: the ball's and the other body's solid indices
                penetrates = self._ball_depths(*args, poses[rows[at]]) > tol
                exact[at] = False
            else:  # args: the two bodies' box pieces
                penetrates = self._box_bodies_penetrate(*args, poses[rows[at], first[k]],
                                                        poses[rows[at], second[k]])
                exact[at] = ~penetrates
            valid[rows[at[penetrates]]] = False
        for row, k in zip(rows[exact], ks[exact], strict=True):
            if not valid[row]:
                continue
            i, j = first[k], second[k]
            depth, _ = _pair_penetration(self.solids[i].built, poses[row, i],
                                         self.solids[j].built, poses[row, j], self.cache)
            if depth > tol:
                valid[row] = False
        return valid

    def _ball_depths(self, ball: int, other: int, poses: np.ndarray) -> np.ndarray:
        """(r,) depth (m, >= 0) of solid ``ball`` into solid ``other`` (primitive pieces) for
        each layout's poses (r, n, 4, 4): :func:`_ball_depth`, vectorised."""
        sphere = self.solids[ball].built.pieces[0]
        centres = np.einsum("rij,j->ri", poses[:, ball], sphere.frame[:, 3])[:, :3]
        to_other = poses[:, other]
        depth = np.zeros(len(poses))
        for piece in self.solids[other].built.pieces:
            frames = to_other @ piece.frame
            local = np.einsum("rji,rj->ri", frames[:, :3, :3], centres - frames[:, :3, 3])
            depth = np.maximum(depth, sphere.radius - signed_distances(piece, local))
        return depth

    def _box_bodies_penetrate(self, boxes_a, boxes_b, pose_a, pose_b) -> np.ndarray:
        """(r,) bool: certain penetration of two box-made solids (see ``__init__``)."""
        frames_a = pose_a[:, None] @ boxes_a[0][None]  # (r, pa, 4, 4)
        frames_b = pose_b[:, None] @ boxes_b[0][None]
        r, pa, pb = len(pose_a), len(boxes_a[0]), len(boxes_b[0])
        shape = (r, pa, pb)
        deep = _boxes_share_a_deep_point(
            np.broadcast_to(frames_a[:, :, None], shape + (4, 4)).reshape(-1, 4, 4),
            np.broadcast_to(boxes_a[1][None, :, None], shape + (3,)).reshape(-1, 3),
            np.broadcast_to(frames_b[:, None, :], shape + (4, 4)).reshape(-1, 4, 4),
            np.broadcast_to(boxes_b[1][None, None, :], shape + (3,)).reshape(-1, 3),
            self.tolerance / 2 + 1e-6)
        return deep.reshape(r, -1).any(axis=1)
