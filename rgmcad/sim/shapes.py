"""Collision shapes: the pybullet shape of a set of collision pieces.

What pybullet shape a piece is gets written once, per piece type (:func:`shape_arguments`,
:func:`mesh_file`, :func:`hull_vertices`). Engine workarounds, all in this module:

* compound bodies take convex pieces from OBJ files because ``createCollisionShapeArray``
  accepts no raw vertices;
* ``createCollisionShapeArray`` keeps 16 children and silently drops the rest (bullet3#2185):
  a body of more pieces gets one OBJ file of several objects per scene body, which pybullet
  loads as one convex hull child per object (:func:`packed`);
* an OBJ file's name is its content's digest: pybullet caches file contents by name
  (``enableFileCaching``), so a name never stands for other content;
* pybullet pads a convex hull by its collision margin (1 mm unless set) and
  ``changeDynamics(collisionMargin=)`` reaches the children of a compound only on a multibody's
  base: every shape gets its margin from a throwaway base at creation (:func:`set_margin`),
  and every hull is inset by that margin (:func:`inset_vertices`), so hull plus margin is the
  piece. Boxes and cylinders keep their size under any margin (it only rounds their edges);
  a sphere's or a capsule's margin is its radius.

Files are derived data of the parts, kept in the caller's :class:`~rgmcad.sim.cache.PartCache`.
"""

from __future__ import annotations

import hashlib
import itertools
import os
from dataclasses import dataclass
from functools import singledispatch

import numpy as np

from rgmcad.geometry import matmul, to_pybullet, transform_points
from rgmcad.parts.pieces import (
    BoxPiece,
    CapsulePiece,
    ConvexPiece,
    CylinderPiece,
    Piece,
    PlanePiece,
    SpherePiece,
)
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import pb

ARRAY_CHILDREN = 16
"""Children ``createCollisionShapeArray`` keeps; it silently drops the others (bullet3#2185)."""


@dataclass(frozen=True, eq=False)
class Hulls:
    """Pieces loaded from one OBJ file of one object per piece: a single entry of
    ``createCollisionShapeArray`` from which pybullet adds one convex hull child per object
    to the compound, however many. Each piece (convex, or a box as the hull of its corners)
    comes with its frame in the entry's frame: its own frame (pieces of one scene body), or
    its frame in the whole body (``baked``: the file then depends on the layout)."""

    pieces: tuple[tuple[ConvexPiece | BoxPiece, np.ndarray], ...]
    baked: bool = False


# --- what pybullet shape a piece is -----------------------------------------------------------


@singledispatch
def shape_arguments(piece) -> dict:
    """``createCollisionShape`` arguments of one piece (its frame aside)."""
    raise TypeError(f"no collision shape for a {type(piece).__name__}")


@shape_arguments.register
def _(piece: BoxPiece) -> dict:
    return {"shapeType": pb.GEOM_BOX, "halfExtents": [s / 2 for s in piece.size]}


@shape_arguments.register
def _(piece: SpherePiece) -> dict:
    return {"shapeType": pb.GEOM_SPHERE, "radius": piece.radius}


@shape_arguments.register
def _(piece: CylinderPiece) -> dict:
    return {"shapeType": pb.GEOM_CYLINDER, "radius": piece.radius, "height": piece.height}


@shape_arguments.register
def _(piece: CapsulePiece) -> dict:  # pybullet's height: between the hemispheres' centres
    return {"shapeType": pb.GEOM_CAPSULE, "radius": piece.radius, "height": piece.length}


@shape_arguments.register
def _(piece: ConvexPiece) -> dict:  # collision_shape gives the vertices, inset by the margin
    return {"shapeType": pb.GEOM_MESH}


@shape_arguments.register
def _(piece: PlanePiece) -> dict:
    return {"shapeType": pb.GEOM_PLANE, "planeNormal": [0, 0, 1]}


@shape_arguments.register
def _(piece: Hulls) -> dict:
    return {"shapeType": pb.GEOM_MESH}


@singledispatch
def mesh_file(piece, cache: PartCache, margin: float) -> str:
    """The OBJ file of a mesh child of a compound (``createCollisionShapeArray`` takes files),
    its hulls inset by ``margin`` (m)."""
    raise TypeError(f"a {type(piece).__name__} has no mesh file")


@mesh_file.register
def _(piece: ConvexPiece, cache: PartCache, margin: float) -> str:
    # the piece's vertices in its own frame: its frame is the child's frame
    return cache.get(("obj", margin), piece,
                     lambda: _write_obj(cache, [inset(piece, margin, cache)]))


@mesh_file.register
def _(piece: Hulls, cache: PartCache, margin: float) -> str:
    pieces = tuple(p for p, _ in piece.pieces)
    if not piece.baked:  # frames are the pieces' own: the pieces say it all
        return cache.get(("hulls obj", margin), pieces,
                         lambda: _write_obj(cache, _placed(piece, margin, cache)))
    blocks = _placed(piece, margin, cache)
    digest = hashlib.sha256(b"".join(b.tobytes() for b in blocks)).hexdigest()
    return cache.get(("baked obj", digest), (), lambda: _write_obj(cache, blocks))


@singledispatch
def hull_vertices(piece) -> np.ndarray:
    """(n, 3) points in the piece's frame whose convex hull is the piece."""
    raise TypeError(f"a {type(piece).__name__} is not the hull of finitely many points")


@hull_vertices.register
def _(piece: BoxPiece) -> np.ndarray:
    corners = np.array(list(itertools.product((-0.5, 0.5), repeat=3)))
    return corners * np.asarray(piece.size, float)


@hull_vertices.register
def _(piece: ConvexPiece) -> np.ndarray:
    return np.asarray(piece.vertices, float)


def inset_vertices(vertices, margin: float) -> np.ndarray:
    """(k, 3) vertices of the convex hull of ``vertices`` (n, 3) with every face moved inward
    by ``margin`` (m): padded by a margin that size, it has the hull's faces again (its edges
    and corners rounded by the margin). A hull too thin for that (inradius under twice the
    margin) is inset by half its inradius, so its faces stand out by the rest."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection

    verts = np.asarray(vertices, float)
    if margin <= 0:
        return verts
    planes = np.unique(np.round(ConvexHull(verts).equations, 13), axis=0)  # n . x + d <= 0
    centre = verts.mean(axis=0)
    depth = -float((planes[:, :3] @ centre + planes[:, 3]).max())
    if depth <= 2 * margin:  # the deepest point instead (Chebyshev centre): max r, n.x + r <= -d
        from scipy.optimize import linprog  # rare: its import alone costs 0.1 s

        found = linprog([0, 0, 0, -1], A_ub=np.hstack([planes[:, :3], np.ones((len(planes), 1))]),
                        b_ub=-planes[:, 3], bounds=[(None, None)] * 3 + [(0, None)])
        if not found.success or found.x[3] <= 1e-9:
            return verts  # flat: nothing to inset
        centre, depth = found.x[:3], float(found.x[3])
    shrunk = planes.copy()
    shrunk[:, 3] += min(margin, depth / 2)
    points = HalfspaceIntersection(shrunk, centre).intersections
    return points[ConvexHull(points).vertices]


def inset(piece, margin: float, cache: PartCache) -> np.ndarray:
    """:func:`inset_vertices` of a piece's :func:`hull_vertices`, once per piece and margin."""
    return cache.get(("inset", margin), piece,
                     lambda: inset_vertices(hull_vertices(piece), margin))


def _placed(hulls: Hulls, margin: float, cache: PartCache) -> list[np.ndarray]:
    """(n, 3) vertices of each piece, inset by ``margin`` and placed at its frame."""
    out = []
    for piece, frame in hulls.pieces:
        verts = inset(piece, margin, cache)
        if not np.array_equal(frame, np.eye(4)):  # else as written for one piece, bit for bit
            verts = transform_points(np.asarray(frame, float), verts)
        out.append(verts)
    return out


def _write_obj(cache: PartCache, blocks: list[np.ndarray]) -> str:
    """An OBJ file of one object (the convex hull of its vertices) per block, in the cache's
    folder, named by its content."""
    from scipy.spatial import ConvexHull

    text, offset = [], 0
    for i, verts in enumerate(blocks):
        if len(blocks) > 1:
            text.append(f"o piece{i}\n")
        hull = ConvexHull(verts)
        text.append("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in verts))
        text.append("".join(f"f {a + offset + 1} {b + offset + 1} {c + offset + 1}\n"
                            for a, b, c in hull.simplices))
        offset += len(verts)
    data = "".join(text).encode()
    path = os.path.join(cache.directory(), hashlib.sha256(data).hexdigest()[:32] + ".obj")
    if not os.path.exists(path):
        with open(path, "wb") as f:
            f.write(data)
    return path


# --- compound shapes ----------------------------------------------------------------------------


def set_margin(engine, shape: int, margin: float) -> None:
    """Give ``shape`` and every child of it the collision margin ``margin`` (m).

    ``changeDynamics(collisionMargin=)`` sets the children's margins only on a multibody's
    base (on a maximal-coordinates body or a link it sets the compound's own), and a margin
    belongs to the shape, shared by every body made from it: so a throwaway base of the shape
    takes the margin and is removed (its body id goes to the next body created)."""
    holder = engine.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape,
                                    basePosition=[0.0, 0.0, -1e3])
    engine.changeDynamics(holder, -1, collisionMargin=margin)
    engine.removeBody(holder)


def collision_shape(engine, pieces: list[tuple[Piece, np.ndarray]], cache: PartCache,
                    margin: float) -> int:
    """A collision shape in ``engine`` (:class:`~rgmcad.sim.engine.Engine`) from pieces
    given with their (4, 4) frame in the shape frame, whose surface is the pieces': hulls
    inset by the collision ``margin`` (m) that every piece is given."""
    if len(pieces) == 1:
        piece, frame = pieces[0]
        pos, orn = to_pybullet(frame)
        args = shape_arguments(piece)
        if isinstance(piece, ConvexPiece):
            args["vertices"] = inset(piece, margin, cache).tolist()
        shape = engine.createCollisionShape(**args, collisionFramePosition=pos,
                                            collisionFrameOrientation=orn)
        if isinstance(piece, (ConvexPiece, BoxPiece, CylinderPiece)):
            set_margin(engine, shape, margin)
        return shape
    if len(pieces) > ARRAY_CHILDREN:  # bodies of 16 pieces or fewer are built as they were
        pieces = packed(pieces)
    types, radii, halves, lengths, files, positions, orientations = [], [], [], [], [], [], []
    for piece, frame in pieces:
        pos, orn = to_pybullet(frame)
        positions.append(pos)
        orientations.append(orn)
        args = shape_arguments(piece)
        if args["shapeType"] == pb.GEOM_PLANE:
            raise ValueError("a plane cannot be part of a compound body")
        types.append(args["shapeType"])
        radii.append(args.get("radius", 0.0))
        halves.append(args.get("halfExtents", [0.0, 0.0, 0.0]))
        lengths.append(args.get("height", 0.0))
        files.append(mesh_file(piece, cache, margin) if args["shapeType"] == pb.GEOM_MESH else "")
    shape = engine.createCollisionShapeArray(
        types, radii=radii, halfExtents=halves, lengths=lengths, fileNames=files,
        meshScales=[[1, 1, 1]] * len(types), collisionFramePositions=positions,
        collisionFrameOrientations=orientations)
    set_margin(engine, shape, margin)
    return shape


def packed(pieces: list[tuple[Piece, np.ndarray]]) -> list[tuple[Piece | Hulls, np.ndarray]]:
    """At most :data:`ARRAY_CHILDREN` entries standing for more pieces, every piece colliding.

    Each scene body's convex pieces become one :class:`Hulls` entry (a scene body: the pieces
    sharing ``frame @ inv(piece.frame)``), so its file does not depend on the layout. Boxes,
    spheres and cylinders stay exact primitives while they fit. If they do not, boxes join their
    body's hulls as the hull of their 8 corners (the same solid, inset and padded by the
    margin like the other hulls); if that is still too many entries (many welded bodies), all
    hulls and the boxes that must go are baked into one file in the body's frame. Spheres and
    cylinders have no exact hull: more than fit is an error.
    """
    if any(isinstance(piece, PlanePiece) for piece, _ in pieces):
        raise ValueError("a plane cannot be part of a compound body")
    # each piece's scene body frame, frame @ inv(piece.frame), for all pieces at once
    own = np.array([piece.frame for piece, _ in pieces], float)
    inverse = np.tile(np.eye(4), (len(pieces), 1, 1))
    inverse[:, :3, :3] = own[:, :3, :3].transpose(0, 2, 1)
    inverse[:, :3, 3] = -matmul(inverse[:, :3, :3], own[:, :3, 3, None])[..., 0]
    outers = matmul(np.array([frame for _, frame in pieces], float), inverse)
    keys = np.round(outers, 12)  # merges frames equal to 1e-12; a body's first piece places it
    # key -> (the scene body's frame, its hull pieces, its primitives with their frames)
    bodies: dict[bytes, tuple[np.ndarray, list, list]] = {}
    for (piece, frame), outer, key in zip(pieces, outers, keys, strict=True):
        body = bodies.setdefault(key.tobytes(), (outer, [], []))
        if isinstance(piece, ConvexPiece):
            body[1].append(piece)
        else:
            body[2].append((piece, frame))
    excess = sum(len(p) + bool(h) for _, h, p in bodies.values()) - ARRAY_CHILDREN
    # demote boxes where it saves most: bodies that already have hulls, then the most boxes
    for _, hulls, prims in sorted(bodies.values(), key=lambda b: (
            not b[1], -sum(isinstance(p, BoxPiece) for p, _ in b[2]))):
        boxes = [i for i, (p, _) in enumerate(prims) if isinstance(p, BoxPiece)]
        if excess <= 0 or len(boxes) < (1 if hulls else 2):
            continue
        moved = boxes[-min(len(boxes), excess + (0 if hulls else 1)):]
        excess -= len(moved) - (0 if hulls else 1)
        hulls.extend(prims[i][0] for i in moved)
        prims[:] = [e for i, e in enumerate(prims) if i not in moved]
    if excess <= 0:
        out: list[tuple[Piece | Hulls, np.ndarray]] = []
        for outer, hulls, prims in bodies.values():
            out.extend(prims)
            if hulls:
                out.append((Hulls(tuple((p, np.asarray(p.frame, float)) for p in hulls)),
                            outer))
        return out
    # one baked file: every hull, and as many boxes as it takes
    baked = [(p, matmul(outer, p.frame)) for outer, hulls, _ in bodies.values()
             for p in hulls]
    prims = [e for _, _, p in bodies.values() for e in p]
    boxes = [i for i, (p, _) in enumerate(prims) if isinstance(p, BoxPiece)]
    over = len(prims) + 1 - ARRAY_CHILDREN
    if over > len(boxes):
        raise ValueError(f"a rigid body of {len(pieces)} collision pieces: pybullet takes "
                         f"{ARRAY_CHILDREN} per body, and spheres and cylinders need one each "
                         f"({len(prims) - len(boxes)} here)")
    moved = boxes[len(boxes) - max(over, 0):]
    baked.extend(prims[i] for i in moved)
    return [e for i, e in enumerate(prims) if i not in moved] + [
        (Hulls(tuple(baked), baked=True), np.eye(4))]
