"""Lever: a plank that turns freely about a fixed axle (a see-saw, a flipper).

Frame: the plank is centred on the origin like a box (``length`` along X, ``width`` along Y,
``thickness`` along Z). The axle is a cylinder along local Y through (pivot_x, 0, pivot_z),
``axle_length`` long and centred on the plank's mid-plane y = 0.

Bodies: the main body ``""`` is the plank (it carries the object's mass); ``"axle"`` is the
static axle. The hinge lets the plank turn about the axle's axis; the two never collide with
each other (the axle usually passes through the plank).
"""

from dataclasses import dataclass

import numpy as np

from rgmcad.parts.family import BoxPiece, CylinderPiece, Family, Hinge

AXLE_OVERHANG = 0.01
"""Default axle length beyond the plank's width (m): 5 mm either side."""


@dataclass(frozen=True)
class Params:
    length: float  # m, plank along X
    width: float  # m, plank along Y
    thickness: float  # m, plank along Z
    pivot_x: float = 0.0  # m, axle centre in the plank frame
    pivot_z: float = 0.0  # m
    axle_radius: float = 0.002  # m
    axle_length: float | None = None  # m, along Y; None means width + AXLE_OVERHANG

    def __post_init__(self):
        if self.axle_length is None:
            object.__setattr__(self, "axle_length", self.width + AXLE_OVERHANG)
        elif isinstance(self.axle_length, int) and not isinstance(self.axle_length, bool):
            object.__setattr__(self, "axle_length", float(self.axle_length))

    def check(self):
        if not isinstance(self.axle_length, int | float) or isinstance(self.axle_length, bool):
            return f"axle_length must be a number, got {self.axle_length!r}"
        if min(self.length, self.width, self.thickness) <= 0:
            return "length, width and thickness must be > 0"
        if self.axle_radius <= 0 or self.axle_length <= 0:
            return "axle_radius and axle_length must be > 0"
        return None


EXAMPLE = Params(length=0.1175, width=0.023, thickness=0.008, pivot_z=0.002, axle_radius=0.002)


def _axle_frame(p: Params) -> np.ndarray:
    """(4, 4) frame of the axle: its Z axis along the part's Y, centred on the pivot."""
    frame = np.eye(4)
    # Columns are the images of the frame's X, Y, Z axes: X -> X, Y -> -Z, Z -> Y.
    frame[:3, :3] = [[1, 0, 0], [0, 0, 1], [0, -1, 0]]
    frame[:3, 3] = (p.pivot_x, 0.0, p.pivot_z)
    return frame


def build(p: Params):
    import cadquery as cq

    plank = cq.Solid.makeBox(
        p.length, p.width, p.thickness,
        pnt=cq.Vector(-p.length / 2, -p.width / 2, -p.thickness / 2),
    )
    axle = cq.Solid.makeCylinder(
        p.axle_radius, p.axle_length,
        pnt=cq.Vector(p.pivot_x, -p.axle_length / 2, p.pivot_z), dir=cq.Vector(0, 1, 0),
    )
    return {"": plank, "axle": axle}


def collision(p: Params):
    return {
        "": [BoxPiece((p.length, p.width, p.thickness))],
        "axle": [CylinderPiece(p.axle_radius, p.axle_length, _axle_frame(p))],
    }


def joints(p: Params):
    return [Hinge(moving="", fixed="axle", point=(p.pivot_x, 0.0, p.pivot_z), axis=(0.0, 1.0, 0.0))]


FAMILY = Family(
    name="lever",
    params=Params,
    build=build,
    collision=collision,
    joints=joints,
    volume=lambda p: p.length * p.width * p.thickness,
    description="plank turning freely about a static axle along Y at (pivot_x, 0, pivot_z)",
)
