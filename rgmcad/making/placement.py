"""Where a raised part's stands go: the face a stand meets, the cells on the base plane
that stay clear of everything else, and the rectangles chosen among them.

For each raised part (:func:`~rgmcad.making.supports.raised_parts`) a :class:`Site` holds
the plane of the part's face that looks towards its base plane (a face of one of its
bodies' boxes, with real area on it; else the plane parallel to the base through its
nearest point) and a grid of 1 mm cells on the base plane around the part. Points of other
bodies (every recorded pose of every moving body, other static parts) that lie under that
plane, within a margin, block the cells they stand over, except points inside the part's own
convex hull (a ball in a goblet: the goblet's wall is between it and the stand); a stand is
a rectangle of clear cells that overlaps the part's contact area. Lengths are metres unless named in mm.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import ConvexHull, QhullError

from rgmcad.geometry import invert, matmul, transform_points
from rgmcad.making.stands import MIN_HEIGHT, Stand
from rgmcad.making.supports import Holding
from rgmcad.scene.bodies import Scene

__all__ = ["PlacementSettings", "Site", "make_site"]


@dataclass(frozen=True)
class PlacementSettings:
    """How stands are placed.

    margin : m kept between a stand and any other body (above the engine's 2 mm contact
        threshold, so a stand never enters a contact manifold).
    cell : m, grid resolution.
    sizes_mm : candidate base rectangles (length along the part, width), largest first.
    min_contact_mm2 : area of the part's face a stand's top must meet.
    long_mm : a part longer than this along its length gets two stands, one near each end.
    """

    margin: float = 0.003
    cell: float = 0.001
    sizes_mm: tuple[tuple[float, float], ...] = (
        (40, 30), (30, 24), (24, 18), (18, 14), (14, 10), (10, 8), (8, 6))
    min_contact_mm2: float = 4.0
    long_mm: float = 80.0


class Site:
    """The place of a raised part's stands: its frame, top plane, contact cells and the
    cells blocked so far (it accumulates: :meth:`block` as runs are recorded).

    Attributes
    ----------
    holding : the part and its base plane.
    frame : (4, 4) world transform: origin on the base plane, z its normal, x along the part.
    top : (3,) ``w = a u + b v + c``, the plane of the part's face in ``frame``.
    part_pose : (4, 4) world pose of the part's first body when the site was made.
    origin : (2,) (u, v) of cell (0, 0)'s centre; ``shape`` the grid's (nu, nv).
    """

    def __init__(self, holding: Holding, frame, top, part_pose, origin, shape, contact,
                 settings: PlacementSettings):
        self.holding, self.frame, self.top = holding, frame, np.asarray(top, float)
        self.part_pose, self.origin, self.settings = part_pose, np.asarray(origin), settings
        self.contact = contact
        self.blocked = np.zeros(shape, bool)
        uu, vv = self.cell_centres()
        a, b, c = self.top
        self.blocked |= a * uu + b * vv + c < MIN_HEIGHT + settings.cell
        self._to_local = invert(frame)
        self.shield: np.ndarray | None = None  # (k, 4) the part's hull planes, in ``frame``
        # a post beside the part (:mod:`rgmcad.making.beside`): the u of the face it meets,
        # the contact cells it needs, and no cap on its size from the contact's extent
        self.face_u: float | None = None
        self.need_cells: int | None = None
        self.free_size = False
        self._slack = settings.margin * math.sqrt(1.0 + a * a + b * b)

    @property
    def name(self) -> str:
        return self.holding.part.name

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        nu, nv = self.blocked.shape if hasattr(self, "blocked") else self.contact.shape
        cell = self.settings.cell
        return np.meshgrid(self.origin[0] + cell * np.arange(nu),
                           self.origin[1] + cell * np.arange(nv), indexing="ij")

    def block(self, points: np.ndarray, part_pose: np.ndarray | None = None) -> int:
        """Block the cells under world ``points`` (n, 3) that lie below the top plane plus
        the margin. ``part_pose``: the part's pose when the points were recorded (its
        stands move with it), None: as designed. Returns the number of points that block."""
        p = transform_points(self.to_local(part_pose), np.asarray(points, float).reshape(-1, 3))
        return self.block_local(p)

    def to_local(self, part_pose: np.ndarray | None = None) -> np.ndarray:
        """(4, 4) world to the site's frame, for points recorded with the part at
        ``part_pose`` (None: as designed)."""
        if part_pose is None:
            return self._to_local
        return matmul(self._to_local, matmul(self.part_pose, invert(part_pose)))

    def bounds(self) -> np.ndarray:
        """(2, 3) the box in the site's frame where a point may block a cell: the grid's
        (u, v) widened by the margin, w from the base to the top's highest corner plus the
        margin."""
        lo = self.origin - self.settings.margin - self.settings.cell
        hi = lo + self.settings.cell * np.array(self.blocked.shape) + 2 * (
            self.settings.margin + self.settings.cell)
        a, b, c = self.top
        w = max(a * u + b * v + c for u in (lo[0], hi[0]) for v in (lo[1], hi[1]))
        return np.array([[lo[0], lo[1], -1e-4], [hi[0], hi[1], w + self._slack]])

    def block_local(self, p: np.ndarray) -> int:
        """:meth:`block` for points (n, 3) already in the site's frame."""
        a, b, c = self.top
        p = p[(p[:, 2] <= a * p[:, 0] + b * p[:, 1] + c + self._slack) & (p[:, 2] > -1e-4)]
        idx = np.rint((p[:, :2] - self.origin) / self.settings.cell).astype(int)
        m = self.settings.margin / self.settings.cell
        ok = np.all((idx >= -m) & (idx < np.array(self.blocked.shape) + m), axis=1)
        if self.shield is not None and ok.any():  # inside the part's hull: the part between
            ok[ok] = (p[ok] @ self.shield[:, :3].T + self.shield[:, 3]).max(axis=1) > -1e-4
        idx = idx[ok]
        if not len(idx):
            return 0
        r = int(math.ceil(m))
        lo, hi = idx.min(0) - r, idx.max(0) + r + 1  # a window around the hits, dilated
        hits = np.zeros(tuple(hi - lo), bool)
        hits[idx[:, 0] - lo[0], idx[:, 1] - lo[1]] = True
        disk = np.hypot(*np.mgrid[-r:r + 1, -r:r + 1]) <= m + 0.5
        hits = ndimage.binary_dilation(hits, disk)
        a0, b0 = np.maximum(lo, 0), np.minimum(hi, self.blocked.shape)
        if np.all(b0 > a0):
            self.blocked[a0[0]:b0[0], a0[1]:b0[1]] |= \
                hits[a0[0] - lo[0]:b0[0] - lo[0], a0[1] - lo[1]:b0[1] - lo[1]]
        return int(len(idx))

    def choose(self, first_label: int) -> list[Stand]:
        """The stands for this part (none when no rectangle fits), labelled from
        ``S<first_label>``: one near the middle of its contact area, or two near its ends
        for a long part."""
        cu = np.nonzero(self.contact.any(axis=1))[0]
        if not len(cu):
            return []
        cell = self.settings.cell
        lo, hi = cu.min(), cu.max()
        length_mm = (hi - lo) * cell * 1000
        if length_mm > self.settings.long_mm:
            targets = [lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo)]
        else:
            targets = [0.5 * (lo + hi)]
        out: list[Stand] = []
        free = ~self.blocked
        for t in targets:
            found = self._rectangle(free, t)
            if found is None:
                continue
            (i0, j0), (ni, nj) = found
            rect = np.zeros_like(free)
            gap = int(round(self.settings.margin / cell))
            rect[max(i0 - gap, 0):i0 + ni + gap, max(j0 - gap, 0):j0 + nj + gap] = True
            free = free & ~rect
            out.append(self._stand(f"S{first_label + len(out)}", i0, j0, ni, nj))
        return out

    def _rectangle(self, free: np.ndarray, target_u: float):
        """((i0, j0), (ni, nj)) cells of the largest candidate rectangle that is all free
        and meets enough contact, nearest the target; None if none."""
        cell_mm = self.settings.cell * 1000
        sf = _summed(free)
        sc = _summed(self.contact)
        cv = np.nonzero(self.contact.any(axis=0))[0]
        target = np.array([target_u, 0.5 * (cv.min() + cv.max())])
        cu = np.nonzero(self.contact.any(axis=1))[0]
        pad = 4.0 / cell_mm  # a stand may overhang the part's face by 2 mm a side
        smallest = np.array(self.settings.sizes_mm[-1]) / cell_mm  # always allowed
        extent = np.maximum(np.array([cu.max() - cu.min(), cv.max() - cv.min()]) + 1 + pad,
                            smallest)
        need = self.settings.min_contact_mm2 / cell_mm ** 2 if self.need_cells is None \
            else self.need_cells
        if self.free_size:
            extent = np.array(self.contact.shape)
        for length, width in self.settings.sizes_mm:
            ni, nj = int(round(length / cell_mm)), int(round(width / cell_mm))
            if ni > extent[0] or nj > extent[1]:
                continue
            full = _box_sums(sf, ni, nj) == ni * nj
            touch = _box_sums(sc, ni, nj) >= need
            ok = np.argwhere(full & touch)
            if len(ok):
                centres = ok + [(ni - 1) / 2, (nj - 1) / 2]
                best = ok[np.argmin(np.linalg.norm(centres - target, axis=1))]
                return (int(best[0]), int(best[1])), (ni, nj)
        return None

    def _stand(self, label, i0, j0, ni, nj) -> Stand:
        cell = self.settings.cell
        u0, v0 = self.origin + cell * (np.array([i0, j0]) - 0.5)
        u1, v1 = u0 + ni * cell, v0 + nj * cell
        if self.face_u is not None:  # a post: against the part's face
            u0 = self.face_u
        corners = np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1]])
        return Stand(label, self.name, self.holding.base.name, self.frame.copy(), corners,
                     self.top.copy())


def _summed(mask: np.ndarray) -> np.ndarray:
    s = np.zeros((mask.shape[0] + 1, mask.shape[1] + 1), np.int64)
    s[1:, 1:] = mask.astype(np.int64).cumsum(0).cumsum(1)
    return s


def _box_sums(s: np.ndarray, ni: int, nj: int) -> np.ndarray:
    """Sums of every ni x nj window (top-left corner indexed) from a summed-area table."""
    return s[ni:, nj:] - s[:-ni, nj:] - s[ni:, :-nj] + s[:-ni, :-nj]


def make_site(scene: Scene, holding: Holding, settings: PlacementSettings = PlacementSettings(),
              reach: float = 0.03) -> Site:
    """The site of a raised part: its face towards the base plane, a grid around it
    (``reach`` m beyond the part on every side) and its contact cells."""
    part, base = holding.part, holding.base
    bodies = [scene.bodies[n] for n in part.bodies]
    world = np.concatenate([b.world_vertices() for b in bodies])
    frame = base.frame()
    local = transform_points(invert(frame), world)
    # x along the part's length on the base plane
    uv = local[:, :2] - local[:, :2].mean(0)
    _, vecs = np.linalg.eigh(uv.T @ uv)
    d = vecs[:, -1]
    turn = np.eye(4)
    turn[:2, :2] = [[d[0], -d[1]], [d[1], d[0]]]
    frame = matmul(frame, turn)
    to_local = invert(frame)
    local = transform_points(to_local, world)
    top, tris = _face(bodies, frame, local)
    lo, hi = local[:, :2].min(0) - reach, local[:, :2].max(0) + reach
    shape = tuple(int(n) for n in np.ceil((hi - lo) / settings.cell) + 1)
    site = Site(holding, frame, top, bodies[0].pose.copy(), lo, shape,
                np.zeros(shape, bool), settings)
    try:
        site.shield = ConvexHull(local).equations
    except QhullError:  # a flat part: no inside
        site.shield = None
    uu, vv = site.cell_centres()
    site.contact = _rasterised(tris, uu, vv)
    if not site.contact.any():  # a thin contact: the cells around its points
        site.contact = _near_points(tris.reshape(-1, 2), uu, vv, 1.5 * settings.cell)
    block_static(scene, site)
    return site


def block_static(scene: Scene, site: Site) -> None:
    """Block the site's cells under the static bodies other than its part's, and those off
    its base's area (a shelf's edge)."""
    base = site.holding.base
    if base.outline is not None:
        uu, vv = site.cell_centres()
        cells = np.column_stack([uu.ravel(), vv.ravel(), np.zeros(uu.size)])
        world = transform_points(site.frame, cells)
        site.blocked |= ~base.on(world, site.settings.margin).reshape(uu.shape)
    own = set(site.holding.part.bodies) | set(base.bodies)
    for other in scene.bodies.values():
        if other.static and not other.plane and other.name not in own:
            site.block(_surface_points(other.built.vertices, other.built.faces, other.pose))


def _face(bodies, frame, local) -> tuple[np.ndarray, np.ndarray]:
    """The top plane (a, b, c) in ``frame`` and the contact triangles (k, 3, 2) (u, v):
    the box face of a body that looks most towards the base, with area on it and the whole
    part beyond it; else the plane parallel to the base at the part's nearest point."""
    best, best_score = None, 0.0
    to_local = invert(frame)
    for body in bodies:
        pose = matmul(to_local, body.pose)
        box = np.asarray(body.built.bbox, float)
        tri = body.built.vertices[body.built.faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        areas = 0.5 * np.linalg.norm(normals, axis=1)
        normals = normals / np.maximum(2 * areas, 1e-30)[:, None]
        for axis in range(3):
            for side, sign in ((0, -1.0), (1, 1.0)):
                n_local = np.zeros(3)
                n_local[axis] = sign
                n = pose[:3, :3] @ n_local  # outward, in the stand frame
                if n[2] > -0.5:
                    continue
                on = (np.abs(normals @ n_local - 1.0) < 1e-3) & (
                    np.abs(tri[:, :, axis] - box[side, axis]).max(axis=1) < 2e-4)
                area = float(areas[on].sum())
                point = transform_points(pose, tri[on].reshape(-1, 3)) if on.any() else None
                if area < 1e-5 or point is None:
                    continue
                offset = float(point[0] @ n)
                if np.any(local @ n > offset + 2e-4):  # something sticks out past it
                    continue
                score = -n[2]
                if score > best_score + 1e-9:
                    best_score = score
                    a, b = -n[0] / n[2], -n[1] / n[2]
                    c = offset / n[2]
                    best = np.array([a, b, c]), point.reshape(-1, 3, 3)[:, :, :2]
    if best is not None:
        return best
    w = local[:, 2]
    near = local[w <= w.min() + 5e-4, :2]
    return np.array([0.0, 0.0, float(w.min())]), np.repeat(near[:, None], 3, axis=1)


def _rasterised(tris: np.ndarray, uu: np.ndarray, vv: np.ndarray) -> np.ndarray:
    """Cells whose centre lies in any of the triangles (k, 3, 2)."""
    out = np.zeros(uu.shape, bool)
    for a, b, c in tris:
        lo, hi = np.minimum(np.minimum(a, b), c), np.maximum(np.maximum(a, b), c)
        sel = (uu >= lo[0]) & (uu <= hi[0]) & (vv >= lo[1]) & (vv <= hi[1])
        if not sel.any():
            continue
        p = np.column_stack([uu[sel], vv[sel]])
        d1, d2, d3 = (_edge(p, a, b), _edge(p, b, c), _edge(p, c, a))
        inside = ((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))
        out[sel] |= inside & ~((d1 == 0) & (d2 == 0) & (d3 == 0))
    return out


def _edge(p, a, b):
    return (b[0] - a[0]) * (p[:, 1] - a[1]) - (b[1] - a[1]) * (p[:, 0] - a[0])


def _near_points(points: np.ndarray, uu, vv, radius: float) -> np.ndarray:
    out = np.zeros(uu.shape, bool)
    for u, v in points:
        out |= np.hypot(uu - u, vv - v) <= radius
    return out


_SAMPLES: dict[int, tuple[np.ndarray, np.ndarray]] = {}


def surface_samples(vertices: np.ndarray, faces: np.ndarray, spacing: float = 0.003) -> np.ndarray:
    """(n, 3) points covering a mesh's surface at most ``spacing`` m apart (its vertices and
    the points of a regular subdivision of each triangle), in the mesh's frame; cached per
    mesh."""
    key = id(vertices)
    if key not in _SAMPLES or _SAMPLES[key][0] is not vertices:
        tri = np.asarray(vertices, float)[np.asarray(faces)]
        pts = [np.asarray(vertices, float)]
        longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
        for k in np.unique(np.ceil(longest / spacing).astype(int)):
            if k < 2:
                continue
            i, j = np.mgrid[0:k + 1, 0:k + 1]
            keep = i + j <= k
            w = np.column_stack([i[keep], j[keep]]) / k
            sel = tri[np.ceil(longest / spacing).astype(int) == k]
            pts.append((sel[:, :1] + w[None, :, :1] * (sel[:, 1:2] - sel[:, :1])
                        + w[None, :, 1:] * (sel[:, 2:3] - sel[:, :1])).reshape(-1, 3))
        _SAMPLES[key] = (vertices, np.concatenate(pts))  # the mesh is kept: ids stay unique
    return _SAMPLES[key][1]


def _surface_points(vertices, faces, pose) -> np.ndarray:
    return transform_points(pose, surface_samples(vertices, faces))
