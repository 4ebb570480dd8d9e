"""Goblet: a truncated-cone cup (a frustum shell with a flat bottom), opening toward +Z.

Frame: the origin is the centre of the outer bottom face; the axis is local Z and the cup spans
z in [0, inner_height + wall].

Geometry. ``bottom_radius`` and ``top_radius`` are OUTER radii at z = 0 and at the rim
z = H = inner_height + wall. The solid is the outer frustum minus the cavity; the cavity's
cone is parallel to the outer cone at normal distance ``wall`` (its radius is the outer radius
minus ``wall / cos(alpha)`` at every height, alpha being the wall's lean from vertical), and
its flat floor is at z = wall. So the bottom and the wall are both ``wall`` thick, measured
normal to their surfaces, and the analytic volume is outer frustum minus inner frustum.

Collision. One convex piece for the bottom slab (z in [0, wall]) and one per angular sector
of the wall (z in [wall, H]), each the convex hull of the sector's corner points; the pieces
never overlap. Straight chords stand for arcs. Every corner sits at ``push`` = (1 + 1 /
cos(pi / sectors)) / 2 times its circle's radius, so each flat face lies half-way between the
chord through the circle's points and the plane tangent to the circle at the sector's middle:

* every surface (outside, cavity, the bottom's rim) is off by at most
  R (1 / cos(pi / sectors) - 1) / 2 either way: inside at each sector's middle, outside at
  its edges (0.09 mm at R = 36 mm for 32 sectors; 0.1 mm at R = 41.7 mm);
* the wall's two faces are parallel planes, so the wall is its thickness to within
  wall (1 / cos(pi / sectors) - 1) (0.01 mm for a 2 mm wall, 32 sectors) at any radius.
  With the outer corners on the outer circle instead (the pieces inside the solid), the wall
  was thinner than its CAD by R (1 - cos(pi / sectors)) / 2 and broke the 0.1 mm law above
  R = 34 mm (docs/decisions.md, 2026-12-08).
"""

import math
from dataclasses import dataclass

import numpy as np

from rgmcad.parts.family import ConvexPiece, Family


@dataclass(frozen=True)
class Params:
    inner_height: float  # m, depth of the cavity (from the inner floor to the rim)
    top_radius: float  # m, outer radius at the rim
    bottom_radius: float  # m, outer radius at the bottom face
    wall: float  # m, thickness of the wall (normal to the cone) and of the bottom
    sectors: int = 32  # number of convex collision pieces around the wall

    def check(self):
        if min(self.inner_height, self.top_radius, self.bottom_radius, self.wall) <= 0:
            return "inner_height, top_radius, bottom_radius and wall must be > 0"
        if self.sectors < 8:
            return "sectors must be >= 8"
        floor_r, rim_r = _inner_radii(self)
        if min(floor_r, rim_r) <= 0:
            return "wall too thick for the radii: the cavity would vanish"
        return None


EXAMPLE = Params(inner_height=0.11, top_radius=0.036, bottom_radius=0.025, wall=0.002)


def _outer_height(p: Params) -> float:
    return p.inner_height + p.wall


def _slope(p: Params) -> float:
    """dr/dz of both cone surfaces (positive when the cup widens upward)."""
    return (p.top_radius - p.bottom_radius) / _outer_height(p)


def _outer_radius(p: Params, z: float) -> float:
    return p.bottom_radius + _slope(p) * z


def _inset(p: Params) -> float:
    """Horizontal distance between the outer and the inner cone: wall / cos(alpha)."""
    return p.wall * math.sqrt(1 + _slope(p) ** 2)


def _inner_radii(p: Params) -> tuple[float, float]:
    """Radii of the cavity at its floor (z = wall) and at the rim (z = H)."""
    d = _inset(p)
    return _outer_radius(p, p.wall) - d, p.top_radius - d


def _push(p: Params) -> float:
    """Factor on a circle's radius giving the corners of the pieces (see the docstring)."""
    return (1 + 1 / math.cos(math.pi / p.sectors)) / 2


def _frustum_solid(r0: float, r1: float, height: float, z0: float = 0.0):
    """Solid frustum along +Z from z0 (radius r0) to z0 + height (radius r1)."""
    import cadquery as cq

    base = cq.Vector(0, 0, z0)
    if math.isclose(r0, r1, rel_tol=1e-12):  # OCC refuses a cone with equal radii
        return cq.Solid.makeCylinder(r0, height, pnt=base)
    return cq.Solid.makeCone(r0, r1, height, pnt=base)


def build(p: Params):
    outer = _frustum_solid(p.bottom_radius, p.top_radius, _outer_height(p))
    floor_r, rim_r = _inner_radii(p)
    # The cavity pokes out above the rim (keeping a positive radius) so the cut has no
    # coplanar faces.
    slope = _slope(p)
    lip = p.wall if slope >= 0 else min(p.wall, rim_r / (2 * -slope))
    cavity = _frustum_solid(floor_r, rim_r + slope * lip, p.inner_height + lip, z0=p.wall)
    return outer.cut(cavity).clean()


def _ring(radius: float, z: float, angles: np.ndarray) -> np.ndarray:
    return np.column_stack(
        [radius * np.cos(angles), radius * np.sin(angles), np.full_like(angles, z)]
    )


def collision(p: Params):
    height = _outer_height(p)
    floor_r, rim_r = _inner_radii(p)
    angles = np.linspace(0, 2 * math.pi, p.sectors, endpoint=False)
    push = _push(p)
    bottom = np.vstack([
        _ring(p.bottom_radius * push, 0.0, angles),
        _ring(_outer_radius(p, p.wall) * push, p.wall, angles),
    ])
    pieces = [ConvexPiece(bottom)]
    # The wall's cross-section is a parallelogram: inner and outer edge at z = wall and z = H.
    section = [(floor_r * push, p.wall), (_outer_radius(p, p.wall) * push, p.wall),
               (p.top_radius * push, height), (rim_r * push, height)]
    step = 2 * math.pi / p.sectors
    for a in angles:
        ends = np.array([a, a + step])
        pieces.append(ConvexPiece(np.vstack([_ring(r, z, ends) for r, z in section])))
    return pieces


def _frustum(r0: float, r1: float, h: float) -> float:
    return math.pi * h / 3 * (r0 * r0 + r0 * r1 + r1 * r1)


def volume(p: Params) -> float:
    floor_r, rim_r = _inner_radii(p)
    return (_frustum(p.bottom_radius, p.top_radius, _outer_height(p))
            - _frustum(floor_r, rim_r, p.inner_height))


FAMILY = Family(
    name="goblet",
    params=Params,
    build=build,
    collision=collision,
    volume=volume,
    description="truncated-cone cup, outer radii at top and bottom, origin at the outer bottom",
)
