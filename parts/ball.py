"""Ball: a solid sphere (marble, steel ball, ping-pong ball filled or not).

Frame: the origin is the centre of the sphere.
"""

import math
from dataclasses import dataclass

from rgmcad.parts.family import Family, SpherePiece


@dataclass(frozen=True)
class Params:
    radius: float  # m

    def check(self):
        return None if self.radius > 0 else "radius must be > 0"


EXAMPLE = Params(radius=0.01)


def build(p: Params):
    import cadquery as cq

    return cq.Solid.makeSphere(p.radius, angleDegrees1=-90, angleDegrees2=90)


def collision(p: Params):
    return [SpherePiece(p.radius)]


FAMILY = Family(
    name="ball",
    params=Params,
    build=build,
    collision=collision,
    volume=lambda p: 4 / 3 * math.pi * p.radius**3,
    description="solid sphere of a given radius, centred on its frame",
)
