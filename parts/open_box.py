"""Open box: a rectangular container open at the top (+Z), with walls of uniform thickness.

Frame: the origin is the centre of the ``length x width x height`` external bounding box
(X, Y, Z). The bottom plate spans the full ``length x width`` footprint and is ``wall`` thick;
the four walls stand on it. The collision pieces tile the solid without overlapping: the
bottom plate, the front and back walls (full length) and the left and right walls between them.
"""

from dataclasses import dataclass

from rgmcad.geometry import translation
from rgmcad.parts.family import BoxPiece, Family


@dataclass(frozen=True)
class Params:
    length: float  # m, external, along X
    width: float  # m, external, along Y
    height: float  # m, external, along Z
    wall: float  # m, thickness of the bottom and of the walls

    def check(self):
        if min(self.length, self.width, self.height, self.wall) <= 0:
            return "length, width, height and wall must be > 0"
        if 2 * self.wall >= min(self.length, self.width):
            return "wall must be less than half the length and half the width"
        if self.wall >= self.height:
            return "wall must be less than height"
        return None


EXAMPLE = Params(length=0.133, width=0.081, height=0.087, wall=0.003)


def _boxes(p: Params):
    """(size, centre) of the 5 boxes that tile the solid: bottom, front/back, left/right."""
    t = p.wall
    wall_h = p.height - t
    wall_z = t / 2  # centre of a wall standing on the bottom plate: (-h/2 + t + h/2) / 2
    y = (p.width - t) / 2
    x = (p.length - t) / 2
    return [
        ((p.length, p.width, t), (0.0, 0.0, (t - p.height) / 2)),
        ((p.length, t, wall_h), (0.0, -y, wall_z)),
        ((p.length, t, wall_h), (0.0, y, wall_z)),
        ((t, p.width - 2 * t, wall_h), (-x, 0.0, wall_z)),
        ((t, p.width - 2 * t, wall_h), (x, 0.0, wall_z)),
    ]


def build(p: Params):
    import cadquery as cq

    outer = cq.Solid.makeBox(
        p.length, p.width, p.height, pnt=cq.Vector(-p.length / 2, -p.width / 2, -p.height / 2)
    )
    # The cavity pokes out above the rim so the cut has no coplanar faces.
    lip = p.height
    cavity = cq.Solid.makeBox(
        p.length - 2 * p.wall,
        p.width - 2 * p.wall,
        p.height - p.wall + lip,
        pnt=cq.Vector(-p.length / 2 + p.wall, -p.width / 2 + p.wall, -p.height / 2 + p.wall),
    )
    return outer.cut(cavity).clean()


def collision(p: Params):
    return [BoxPiece(size, translation(centre)) for size, centre in _boxes(p)]


def volume(p: Params) -> float:
    inner = (p.length - 2 * p.wall) * (p.width - 2 * p.wall) * (p.height - p.wall)
    return p.length * p.width * p.height - inner


FAMILY = Family(
    name="open_box",
    params=Params,
    build=build,
    collision=collision,
    volume=volume,
    description="rectangular box open at the top (+Z), external size and wall thickness, centred",
)
