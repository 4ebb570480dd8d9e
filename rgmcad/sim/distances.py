"""Signed distances to the primitive collision pieces (boxes, balls, cylinders, capsules):
exact, negative inside, for points in the piece's own frame."""

from __future__ import annotations

from functools import singledispatch

import numpy as np

from rgmcad.geometry import invert, transform_points
from rgmcad.parts.pieces import BoxPiece, CapsulePiece, CylinderPiece, SpherePiece


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
