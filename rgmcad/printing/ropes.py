"""Ropes on a template: each rope's path (hook, pulley points, hook) drawn on the plan view
with its hooks and pulleys circled, and labelled with the length to cut it to, which the
parts list repeats. The path is the straight segments the simulation pulls along, at the
layout's start, projected on the template plane (its true length is in the label).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from shapely.geometry import LineString

from rgmcad.printing.labels import NAME_MM, NOTE_MM
from rgmcad.printing.plane import PlaneFrame

ROPE_RGB = (0.55, 0.1, 0.1)
"""Colour of a rope's path on the drawing."""
ROPE_MM = 0.5
"""Stroke width of a rope's path, mm."""
POINT_MM = 1.2
"""Radius of the circle at a hook or pulley point, mm."""


@dataclass(frozen=True, eq=False)
class PlacedRope:
    """One rope of a layout: ``points`` (k, 3) world metres of its path at the start (first
    hook, pulley points, second hook), what each point is on (``on``: an object's name, or
    ``"world"``), its ``length`` (m) and its path's length at the start ``path_length`` (m)."""

    name: str
    points: np.ndarray
    on: tuple[str, ...]
    length: float
    path_length: float


@dataclass(frozen=True, eq=False)
class RopeOutline:
    """A rope as drawn: ``path_mm`` (k, 2) drawing mm of its path's points, and its label's
    box ``(u0, v0, u1, v1)`` drawing mm."""

    rope: PlacedRope
    path_mm: np.ndarray
    label_box: tuple[float, float, float, float]

    @property
    def name(self) -> str:
        return self.rope.name

    @property
    def outline(self) -> LineString:
        """The path as a shapely line (which sheets show it)."""
        return LineString(self.path_mm)


def scene_ropes(scene) -> list[PlacedRope]:
    """The ropes of a posed scene."""
    return [PlacedRope(r.name, np.asarray(r.points, float),
                       tuple(o or "world" for o in r.objects), float(r.length),
                       float(r.initial_length)) for r in scene.ropes]


def cut_note(rope: PlacedRope) -> str:
    """``"cut 500 mm (+ knots); path 481 mm at the start"``."""
    return (f"cut {rope.length * 1000:.0f} mm (+ knots); path {rope.path_length * 1000:.0f} mm "
            "at the start")


def route(rope: PlacedRope) -> str:
    """``"cage -> 2 pulleys -> gate"``."""
    k = len(rope.on) - 2
    middle = [f"{k} pulle{'ys' if k > 1 else 'y'}"] if k else []
    return " -> ".join([rope.on[0], *middle, rope.on[-1]])


def rope_lines(rope: PlacedRope) -> list[tuple[str, float, bool]]:
    """A rope's label as ``(text, size mm, bold)`` lines."""
    return [(f"rope {rope.name}", NAME_MM, True), (cut_note(rope), NOTE_MM, False),
            (route(rope), NOTE_MM, False)]


def rope_path(rope: PlacedRope, frame: PlaneFrame) -> np.ndarray:
    """(k, 2) drawing mm of the rope's path points."""
    return frame.to_drawing(rope.points)


def point_ring(centre: np.ndarray) -> np.ndarray:
    """(24, 2) drawing mm: the circle drawn at a hook or pulley point."""
    angles = np.linspace(0, 2 * np.pi, 25)[:-1]
    return centre + POINT_MM * np.stack([np.cos(angles), np.sin(angles)], axis=1)


def rope_rows(ropes, sheets) -> list[str]:
    """The parts list's rows of the ropes (:class:`RopeOutline`): name, sheets, the length to
    cut and the route."""
    from shapely.geometry import box

    rows = []
    for r in ropes:
        on = [s.label for s in sheets if r.outline.intersects(box(*s.keep_mm))]
        where = f" [sheet {', '.join(on)}]" if on else ""
        rows.append(f"rope {r.name}{where}: {cut_note(r.rope)}, {route(r.rope)}")
    return rows
