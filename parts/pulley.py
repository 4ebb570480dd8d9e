"""Pulley: a wheel that turns freely on a fixed axle (SPEC 1.13: a cylinder on a hinge).

Frame: the wheel is a solid cylinder of ``radius`` centred on the origin, its axis along local
Y and ``width`` long. The axle is a thinner cylinder on the same axis, ``axle_length`` long.

Bodies: the main body ``""`` is the wheel (it carries the object's mass); ``"axle"`` is the
static axle. The hinge lets the wheel spin about Y; the two never collide with each other. A
rope over a pulley runs over a fixed point (see ``pulleys`` of a rope): put it on the rim,
e.g. ``{ object = "wheel", point = [0, 0, radius] }`` on a static wheel.
"""

import math
from dataclasses import dataclass

import numpy as np

from rgmcad.parts.family import CylinderPiece, Family, Hinge

AXLE_OVERHANG = 0.01
"""Default axle length beyond the wheel's width (m): 5 mm either side."""


@dataclass(frozen=True)
class Params:
    radius: float  # m, wheel
    width: float  # m, wheel along Y
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
        if self.radius <= 0 or self.width <= 0:
            return "radius and width must be > 0"
        if not 0 < self.axle_radius < self.radius:
            return "axle_radius must be > 0 and smaller than radius"
        if self.axle_length <= 0:
            return "axle_length must be > 0"
        return None


EXAMPLE = Params(radius=0.02, width=0.01, axle_radius=0.002)

_ALONG_Y = np.array([[1.0, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]])
"""A cylinder piece's frame whose Z axis is the part's Y axis."""


def build(p: Params):
    import cadquery as cq

    def along_y(radius, length):
        return cq.Solid.makeCylinder(radius, length, pnt=cq.Vector(0, -length / 2, 0),
                                     dir=cq.Vector(0, 1, 0))

    return {"": along_y(p.radius, p.width), "axle": along_y(p.axle_radius, p.axle_length)}


def collision(p: Params):
    return {"": [CylinderPiece(p.radius, p.width, _ALONG_Y)],
            "axle": [CylinderPiece(p.axle_radius, p.axle_length, _ALONG_Y)]}


def joints(p: Params):
    return [Hinge(moving="", fixed="axle", point=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0))]


FAMILY = Family(
    name="pulley",
    params=Params,
    build=build,
    collision=collision,
    joints=joints,
    volume=lambda p: math.pi * p.radius**2 * p.width,
    description="wheel (cylinder along Y) spinning freely on a static axle through its centre",
)
