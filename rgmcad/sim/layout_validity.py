"""Validity of many layouts of one scenario at once, without the details: the yes/no answers
of :func:`~rgmcad.sim.validity.check_validity` (:class:`LayoutValidity`, the samplers' case).

One layout whose scene is built (a simulation's) is tested fastest by ``check_validity``
itself: 0.23 ms on simple against 0.44 ms for one row here (docs/decisions.md).
"""

from __future__ import annotations

import manifold3d
import numpy as np

from rgmcad.geometry import matmul
from rgmcad.parts.pieces import BoxPiece
from rgmcad.parts.store import BuiltBody
from rgmcad.scene.ropes import path_of, ropes_fit_many, world_points
from rgmcad.sim.cache import PartCache
from rgmcad.sim.distances import _PRIMITIVES, signed_distances
from rgmcad.sim.rope_validity import RopePath, rope_crossings
from rgmcad.sim.validity import (
    TOLERANCE,
    _boxes_apart,
    _is_ball,
    _manifold,
    _pair_penetration,
    _plane_depth,
    check_validity,
)

MAX_VECTOR_PAIRS = 20_000
"""Pairs of solids (200 solids) past which layouts are tested one scene at a time by
:func:`check_validity`, whose work is bounded: the vectorised tests hold every pair for every
layout (two crossing runs of 300 wide dominoes: 14 s for one layout, of 1,000: minutes)."""


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
    faster than one scene at a time (figures in docs/decisions.md). Past MAX_VECTOR_PAIRS pairs
    of solids, one scene at a time by :func:`check_validity` after all.

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
        self.parts = parts
        self.one_by_one = n * (n - 1) // 2 > MAX_VECTOR_PAIRS
        if self.one_by_one:
            return
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
        if self.one_by_one:
            from rgmcad.scene.bodies import make_scene

            return np.array([check_validity(make_scene(self.scenario, v, self.parts),
                                            self.tolerance, True, self.cache).valid
                             for v in values], dtype=bool)
        m, n, tol = len(values), len(self.solids), self.tolerance
        valid = np.ones(m, dtype=bool)
        if n == 0 or m == 0:
            return valid
        world = world_poses_many(self.scenario, values)
        valid &= ropes_fit_many(self.scenario, world, tol)  # ropes long enough for their path
        if self.scenario.ropes and valid.any():
            bodies = self.solids + self.planes
            paths = [RopePath(r.name, tuple(p.object for p in path_of(r)),
                              world_points(self.scenario, r, world))
                     for r in self.scenario.ropes.values()]
            crossed = rope_crossings(bodies, np.stack([world[b.object] for b in bodies], axis=1),
                                     paths, tol, self.cache, rows=np.flatnonzero(valid),
                                     exact=False)
            valid[[c.row for c in crossed]] = False
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
            if not valid.any():
                break
            if self.shortcuts[k] is None:
                continue
            at = np.flatnonzero((ks == k) & valid[rows])  # a layout found invalid is done
            if len(at) == 0:
                continue
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
            frames = matmul(to_other, piece.frame)
            local = np.einsum("rji,rj->ri", frames[:, :3, :3], centres - frames[:, :3, 3])
            depth = np.maximum(depth, sphere.radius - signed_distances(piece, local))
        return depth

    def _box_bodies_penetrate(self, boxes_a, boxes_b, pose_a, pose_b) -> np.ndarray:
        """(r,) bool: certain penetration of two box-made solids (see ``__init__``)."""
        frames_a = matmul(pose_a[:, None], boxes_a[0][None])  # (r, pa, 4, 4)
        frames_b = matmul(pose_b[:, None], boxes_b[0][None])
        r, pa, pb = len(pose_a), len(boxes_a[0]), len(boxes_b[0])
        shape = (r, pa, pb)
        deep = _boxes_share_a_deep_point(
            np.broadcast_to(frames_a[:, :, None], shape + (4, 4)).reshape(-1, 4, 4),
            np.broadcast_to(boxes_a[1][None, :, None], shape + (3,)).reshape(-1, 3),
            np.broadcast_to(frames_b[:, None, :], shape + (4, 4)).reshape(-1, 4, 4),
            np.broadcast_to(boxes_b[1][None, None, :], shape + (3,)).reshape(-1, 3),
            self.tolerance / 2 + 1e-6)
        return deep.reshape(r, -1).any(axis=1)

