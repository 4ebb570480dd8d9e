"""Capsule: a cylinder with a hemisphere on each end (a rope segment, a rounded peg).

Frame: the origin is the capsule's centre and its axis is local Z. ``length`` is the distance
between the two hemispheres' centres (the cylinder's length, the paper's capsule "height"), so
the capsule reaches z = +-(length / 2 + radius). Its collision piece is the exact capsule.
"""

import math
from dataclasses import dataclass

from rgmcad.parts.family import CapsulePiece, Family


@dataclass(frozen=True)
class Params:
    radius: float  # m
    length: float  # m, between the hemispheres' centres, along Z

    def check(self):
        if self.radius <= 0:
            return "radius must be > 0"
        if self.length < 0:
            return "length must be >= 0 (0: a ball)"
        return None


EXAMPLE = Params(radius=0.01, length=0.02)


def build(p: Params):
    import cadquery as cq

    solid = cq.Solid.makeSphere(p.radius, pnt=cq.Vector(0, 0, -p.length / 2), angleDegrees1=-90,
                                angleDegrees2=90)
    if p.length > 0:
        solid = solid.fuse(
            cq.Solid.makeCylinder(p.radius, p.length, pnt=cq.Vector(0, 0, -p.length / 2)),
            cq.Solid.makeSphere(p.radius, pnt=cq.Vector(0, 0, p.length / 2), angleDegrees1=-90,
                                angleDegrees2=90)).clean()
    return solid


def collision(p: Params):
    return [CapsulePiece(p.radius, p.length)]


FAMILY = Family(
    name="capsule",
    params=Params,
    build=build,
    collision=collision,
    volume=lambda p: math.pi * p.radius**2 * (p.length + 4 * p.radius / 3),
    description="cylinder capped by two hemispheres along Z (length between their centres)",
)
