"""Box: a rectangular block (plank, wall, domino), centred on its frame.

Frame: the origin is the box's centre; ``length`` runs along local X, ``width`` along Y and
``height`` along Z (full side lengths). A domino topples along its thin axis, so give it its
thickness as ``length``.
"""

from dataclasses import dataclass

from rgmcad.parts.family import BoxPiece, Family


@dataclass(frozen=True)
class Params:
    length: float  # m, along X
    width: float  # m, along Y
    height: float  # m, along Z

    def check(self):
        if min(self.length, self.width, self.height) <= 0:
            return "length, width and height must be > 0"
        return None


EXAMPLE = Params(length=0.007, width=0.022, height=0.044)
"""A domino: 7 x 22 x 44 mm."""


def build(p: Params):
    import cadquery as cq

    return cq.Solid.makeBox(
        p.length, p.width, p.height, pnt=cq.Vector(-p.length / 2, -p.width / 2, -p.height / 2)
    )


def collision(p: Params):
    return [BoxPiece((p.length, p.width, p.height))]


FAMILY = Family(
    name="box",
    params=Params,
    build=build,
    collision=collision,
    volume=lambda p: p.length * p.width * p.height,
    description="rectangular block length x width x height (X, Y, Z), centred on its frame",
)
