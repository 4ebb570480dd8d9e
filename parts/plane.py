"""Plane: an infinite static plane, the ground or a back board.

Frame: the surface is the local z = 0 plane with normal +Z; the solid side is z < 0. Posed
with pitch -90 degrees its normal becomes +Y (a back board behind a ball run). It has no mesh,
no mass and no CAD solid.
"""

from dataclasses import dataclass

from rgmcad.parts.family import Family, PlanePiece


@dataclass(frozen=True)
class Params:
    """No parameters: size and place come from the object's pose."""


EXAMPLE = Params()


def collision(p: Params):
    return [PlanePiece()]


FAMILY = Family(
    name="plane",
    params=Params,
    build=None,
    collision=collision,
    infinite=True,
    description="infinite static plane z = 0 with normal +Z, solid below",
)
