"""Track: a straight rail with a square groove, open at both ends, for balls to roll along.

Frame: the origin is the centre of the ``length x width x height`` bounding box; the rail runs
along local X, the groove opens toward +Z. The floor is ``wall`` thick at the bottom of the
bounding box and the two side walls are ``wall`` thick and full height, so the groove is
``width - 2 wall`` wide and ``height - wall`` deep. A positive roll lowers the +X end.
"""

from dataclasses import dataclass

from rgmcad.geometry import translation
from rgmcad.parts.family import BoxPiece, Family


@dataclass(frozen=True)
class Params:
    length: float  # m, along X
    width: float  # m, external, along Y
    height: float  # m, external, along Z
    wall: float  # m, thickness of the floor and of the side walls

    def check(self):
        if min(self.length, self.width, self.height, self.wall) <= 0:
            return "length, width, height and wall must be > 0"
        if 2 * self.wall >= self.width:
            return "wall must be less than width / 2 (the groove would vanish)"
        if self.wall >= self.height:
            return "wall must be less than height (the groove would vanish)"
        return None


EXAMPLE = Params(length=0.3, width=0.025, height=0.008, wall=0.002)


def _boxes(p: Params):
    """(size, centre) of the floor and the two side walls: they tile the solid exactly."""
    inner = p.width - 2 * p.wall
    side_y = (p.width - p.wall) / 2
    return [
        ((p.length, inner, p.wall), (0.0, 0.0, (p.wall - p.height) / 2)),
        ((p.length, p.wall, p.height), (0.0, -side_y, 0.0)),
        ((p.length, p.wall, p.height), (0.0, side_y, 0.0)),
    ]


def build(p: Params):
    import cadquery as cq

    outer = cq.Solid.makeBox(
        p.length, p.width, p.height, pnt=cq.Vector(-p.length / 2, -p.width / 2, -p.height / 2)
    )
    # The groove pokes out at both ends and above the top so the cut has no coplanar faces;
    # what is left is exactly the floor and the two side walls of ``_boxes``.
    lip = p.height
    groove = cq.Solid.makeBox(
        p.length + 2 * lip,
        p.width - 2 * p.wall,
        p.height - p.wall + lip,
        pnt=cq.Vector(-p.length / 2 - lip, -p.width / 2 + p.wall, -p.height / 2 + p.wall),
    )
    return outer.cut(groove).clean()


def collision(p: Params):
    return [BoxPiece(size, translation(centre)) for size, centre in _boxes(p)]


FAMILY = Family(
    name="track",
    params=Params,
    build=build,
    collision=collision,
    volume=lambda p: p.length * (p.width * p.height - (p.width - 2 * p.wall) * (p.height - p.wall)),
    description="straight rail with a square groove (floor + 2 side walls), centred bounding box",
)
