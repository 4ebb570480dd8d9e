"""Collision pieces: the convex shapes physics sees a part body as.

Each piece is convex and sits at ``frame``, a (4, 4) transform in the part's frame. A piece
type writes and reads its own fields (``to_dict``, :func:`piece_from_dict`), for
``part.json``; :data:`PIECES` is the registry of piece types by the ``kind`` written there.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np


def _identity() -> np.ndarray:
    return np.eye(4)


class _Piece:
    """What every piece type shares: its ``kind`` and its dict form."""

    kind: ClassVar[str]

    def to_dict(self) -> dict:
        """JSON-ready dict: ``kind``, ``frame`` (4 x 4 list), then the type's own fields."""
        return {"kind": self.kind, "frame": np.asarray(self.frame, float).tolist(),
                **self._fields_dict()}

    def _fields_dict(self) -> dict:
        return {}

    @classmethod
    def _from_fields(cls, data: Mapping, frame: np.ndarray):
        return cls(frame=frame)


@dataclass(frozen=True, eq=False)
class BoxPiece(_Piece):
    """A box of full side lengths ``size`` (3,) in metres, centred on its frame."""

    size: tuple[float, float, float]
    frame: np.ndarray = field(default_factory=_identity)
    kind: ClassVar[str] = "box"

    def _fields_dict(self) -> dict:
        return {"size": [float(s) for s in self.size]}

    @classmethod
    def _from_fields(cls, data: Mapping, frame: np.ndarray):
        return cls(tuple(data["size"]), frame)


@dataclass(frozen=True, eq=False)
class SpherePiece(_Piece):
    """A ball of ``radius`` metres, centred on its frame."""

    radius: float
    frame: np.ndarray = field(default_factory=_identity)
    kind: ClassVar[str] = "sphere"

    def _fields_dict(self) -> dict:
        return {"radius": float(self.radius)}

    @classmethod
    def _from_fields(cls, data: Mapping, frame: np.ndarray):
        return cls(data["radius"], frame)


@dataclass(frozen=True, eq=False)
class CylinderPiece(_Piece):
    """A cylinder along its frame's Z axis, centred on its frame."""

    radius: float
    height: float
    frame: np.ndarray = field(default_factory=_identity)
    kind: ClassVar[str] = "cylinder"

    def _fields_dict(self) -> dict:
        return {"radius": float(self.radius), "height": float(self.height)}

    @classmethod
    def _from_fields(cls, data: Mapping, frame: np.ndarray):
        return cls(data["radius"], data["height"], frame)


@dataclass(frozen=True, eq=False)
class CapsulePiece(_Piece):
    """A capsule along its frame's Z axis, centred on its frame: the points within ``radius``
    of the segment of ``length`` between its two hemispheres' centres."""

    radius: float
    length: float
    frame: np.ndarray = field(default_factory=_identity)
    kind: ClassVar[str] = "capsule"

    def _fields_dict(self) -> dict:
        return {"radius": float(self.radius), "length": float(self.length)}

    @classmethod
    def _from_fields(cls, data: Mapping, frame: np.ndarray):
        return cls(data["radius"], data["length"], frame)


@dataclass(frozen=True, eq=False)
class ConvexPiece(_Piece):
    """The convex hull of ``vertices`` (n, 3), given in the piece's frame."""

    vertices: np.ndarray
    frame: np.ndarray = field(default_factory=_identity)
    kind: ClassVar[str] = "convex"

    def _fields_dict(self) -> dict:
        return {"vertices": np.asarray(self.vertices, float).tolist()}

    @classmethod
    def _from_fields(cls, data: Mapping, frame: np.ndarray):
        return cls(np.asarray(data["vertices"], float), frame)


@dataclass(frozen=True, eq=False)
class PlanePiece(_Piece):
    """The infinite half-space z <= 0 of its frame (its surface has normal +Z)."""

    frame: np.ndarray = field(default_factory=_identity)
    kind: ClassVar[str] = "plane"


Piece = BoxPiece | SpherePiece | CylinderPiece | CapsulePiece | ConvexPiece | PlanePiece

PIECES: dict[str, type] = {
    "box": BoxPiece,
    "sphere": SpherePiece,
    "cylinder": CylinderPiece,
    "capsule": CapsulePiece,
    "convex": ConvexPiece,
    "plane": PlanePiece,
}
"""Piece types by the ``kind`` written in ``part.json``."""


def piece_from_dict(data: Mapping) -> Piece:
    """The piece that ``piece.to_dict()`` describes."""
    kind = data["kind"]
    if kind not in PIECES:
        raise ValueError(f"unknown collision piece kind {kind!r}; allowed: {', '.join(PIECES)}")
    return PIECES[kind]._from_fields(data, np.asarray(data["frame"], float))
