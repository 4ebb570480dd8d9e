"""Cylinder: a solid circular cylinder along local Z, centred on its frame.

Frame: the origin is the centre of the cylinder (half-way along its axis); the axis is local
Z and ``height`` is the full height, so the faces lie at z = -height/2 and z = +height/2.
"""

import math
from dataclasses import dataclass

from rgmcad.parts.family import CylinderPiece, Family


@dataclass(frozen=True)
class Params:
    radius: float  # m
    height: float  # m, full height along Z

    def check(self):
        if self.radius <= 0:
            return "radius must be > 0"
        if self.height <= 0:
            return "height must be > 0"
        return None


EXAMPLE = Params(radius=0.01, height=0.03)


def build(p: Params):
    import cadquery as cq

    return cq.Solid.makeCylinder(p.radius, p.height, pnt=cq.Vector(0, 0, -p.height / 2))


def collision(p: Params):
    return [CylinderPiece(p.radius, p.height)]


FAMILY = Family(
    name="cylinder",
    params=Params,
    build=build,
    collision=collision,
    volume=lambda p: math.pi * p.radius**2 * p.height,
    description="solid cylinder of a given radius and full height along Z, centred on its frame",
)
