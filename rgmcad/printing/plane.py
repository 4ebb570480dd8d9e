"""The plane a template is drawn in, and the projection of world points onto it.

*World* coordinates are metres, Z up. *Drawing* coordinates are millimetres in the template
plane, ``u`` to the right and ``v`` up as the builder sees the plane (from the side its
normal points to), so the drawing is never mirrored: ``u_axis x v_axis = normal``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rgmcad.printing.inputs import BasePlane

PLANES = ("floor", "board", "xy", "xz", "yz")
"""Planes a template may be drawn in by kind; a base plane's own name works too."""

_TOUCH_M = 0.005  # a part whose lowest point is this close to a base plane rests on it


@dataclass(frozen=True, eq=False)
class PlaneFrame:
    """The plane a template is drawn in, as the builder sees it.

    Attributes
    ----------
    kind : str
        ``"floor"``, ``"board"``, ``"xy"``, ``"xz"``, ``"yz"`` or ``"plane"`` (another base
        plane).
    base : str
        Name of the base plane, ``""`` for an axis plane.
    origin : (3,) float
        World point of drawing coordinates (0, 0), metres.
    u_axis, v_axis, normal : (3,) float
        World directions of the drawing's right, up, and towards the viewer;
        ``u_axis x v_axis = normal``.
    """

    kind: str
    base: str
    origin: np.ndarray
    u_axis: np.ndarray
    v_axis: np.ndarray
    normal: np.ndarray

    def to_drawing(self, points: np.ndarray) -> np.ndarray:
        """(n, 2) drawing mm of (n, 3) world points (metres), projected along the normal."""
        d = np.asarray(points, float).reshape(-1, 3) - self.origin
        return 1000.0 * np.column_stack([d @ self.u_axis, d @ self.v_axis])

    def to_world(self, uv_mm: np.ndarray) -> np.ndarray:
        """(n, 3) world points (metres, on the plane) of (n, 2) drawing mm."""
        uv = np.asarray(uv_mm, float).reshape(-1, 2) / 1000.0
        return self.origin + uv[:, :1] * self.u_axis + uv[:, 1:] * self.v_axis

    def height(self, points: np.ndarray) -> np.ndarray:
        """(n,) signed distances of (n, 3) world points from the plane, metres."""
        return (np.asarray(points, float).reshape(-1, 3) - self.origin) @ self.normal


def plane_frame(point, normal, kind: str = "plane", base: str = "") -> PlaneFrame:
    """Frame of the plane through ``point`` with unit ``normal``, seen from the normal's side.

    On a tilted or vertical plane ``v`` is world +Z projected on the plane (up on paper is up
    in the world); on a horizontal plane ``u`` is world +X. E.g. a board with normal +Y is
    seen from +Y: up is +Z and right is -X.
    """
    n = np.asarray(normal, float)
    n = n / np.linalg.norm(n)
    z = np.array([0.0, 0.0, 1.0])
    vz = z - (z @ n) * n
    if np.linalg.norm(vz) > 1e-6:
        v = vz / np.linalg.norm(vz)
        u = np.cross(v, n)
    else:
        x = np.array([1.0, 0.0, 0.0])
        u = x - (x @ n) * n
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
    return PlaneFrame(kind, base, np.asarray(point, float).copy(), u, v, n)


AXIS_FRAMES = {
    "xy": ((1.0, 0, 0), (0, 1.0, 0)),  # seen from +Z
    "xz": ((1.0, 0, 0), (0, 0, 1.0)),  # seen from -Y (the paper's 'xz')
    "yz": ((0, 1.0, 0), (0, 0, 1.0)),  # seen from +X
}
"""Axis planes: name -> (u right, v up), world directions; the viewer is on the side of
``u x v``."""


def _axis_frame(name: str) -> PlaneFrame:
    u, v = (np.array(a, float) for a in AXIS_FRAMES[name])
    return PlaneFrame(name, "", np.zeros(3), u, v, np.cross(u, v))


def _is_horizontal(bp: BasePlane) -> bool:
    n = np.asarray(bp.normal, float)
    return abs(n[2]) / np.linalg.norm(n) > math.cos(math.radians(5))


def _is_vertical(bp: BasePlane) -> bool:
    n = np.asarray(bp.normal, float)
    return abs(n[2]) / np.linalg.norm(n) < math.sin(math.radians(5))


def _touching(parts, bp: BasePlane) -> int:
    n = np.asarray(bp.normal, float)
    n = n / np.linalg.norm(n)
    count = 0
    for p in parts:
        low = float(np.min((np.asarray(p.vertices) - bp.point) @ n))
        count += abs(low) <= _TOUCH_M
    return count


def _base_frame(bp: BasePlane) -> PlaneFrame:
    kind = "floor" if _is_horizontal(bp) else "board" if _is_vertical(bp) else "plane"
    return plane_frame(bp.point, bp.normal, kind, bp.name)


def resolve_plane(parts, base_planes, plane: str | None = None) -> PlaneFrame:
    """The frame a template is drawn in.

    Parameters
    ----------
    parts : sequence of PlacedPart
    base_planes : sequence of BasePlane
    plane : str or None
        ``"floor"`` (a horizontal base plane), ``"board"`` (a vertical base plane), an axis
        plane ``"xy"`` (seen from +Z), ``"xz"`` (seen from -Y: x right, z up), ``"yz"``
        (seen from +X), or the name of a base plane. Where several base planes fit, the one
        the most parts rest on (lowest point within 5 mm) wins. None chooses: the base plane
        the most parts rest on, a vertical one winning ties (a board is where the template
        goes); with no base plane, the axis plane across the layout's thinnest extent
        (``"xy"`` unless the layout is clearly flat in y or x).
    """
    planes = list(base_planes)
    if plane is None:
        if planes:
            scored = [(_touching(parts, bp), _is_vertical(bp), -i) for i, bp in enumerate(planes)]
            best = max(range(len(planes)), key=lambda i: scored[i])
            return _base_frame(planes[best])
        pts = np.concatenate([np.asarray(p.vertices, float) for p in parts])
        ext = pts.max(0) - pts.min(0)
        if ext[1] < 0.25 * min(ext[0], ext[2]):
            return _axis_frame("xz")
        if ext[0] < 0.25 * min(ext[1], ext[2]):
            return _axis_frame("yz")
        return _axis_frame("xy")
    if plane in AXIS_FRAMES:
        return _axis_frame(plane)
    if plane in ("floor", "board"):
        fits = _is_horizontal if plane == "floor" else _is_vertical
        cands = [bp for bp in planes if fits(bp)]
        if not cands:
            names = ", ".join(bp.name for bp in planes) or "none"
            raise ValueError(
                f"plane {plane!r}: the scenario has no "
                f"{'horizontal' if plane == 'floor' else 'vertical'} base plane "
                f"(base planes: {names}); use one of xy, xz, yz"
            )
        best = max(cands, key=lambda bp: _touching(parts, bp))
        return plane_frame(best.point, best.normal, plane, best.name)
    for bp in planes:
        if bp.name == plane:
            return _base_frame(bp)
    valid = [*PLANES, *(bp.name for bp in planes)]
    raise ValueError(f"unknown plane {plane!r}; choose one of {', '.join(valid)}")
