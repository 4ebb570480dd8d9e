"""Where neighbouring sheets meet: one seam line per pair, the area each sheet keeps, and the
matching marks that fix a sheet's position along its seam.

Neighbouring sheets show a common strip of ``overlap`` mm. Each pair has exactly one seam
line, through the middle of that strip, and both sheets draw it at the same drawing
coordinates, so the rule a maker follows is right by construction: the sheet on the right
(or below) is cut along the seam line and laid on the sheet on the left (or above) with its
cut edge on that sheet's copy of the line. What a sheet keeps (``keep_mm``) is therefore the
area between its seam lines (its window's own edge where it has no neighbour); the strip
beyond a right or bottom seam line lies under the neighbour.

Matching marks are short strokes across a seam line, drawn on both sheets at the same place
and labelled with the same letter pair (``"AB"``) on each sheet's kept side: once the cut
edge lies on the line, the strokes of a pair meet, which fixes the sheet along the seam.
"""

from __future__ import annotations

import string
from dataclasses import dataclass

MARK_SPACING_MM = 45.0
"""Largest distance between matching marks along a seam."""
MARK_INSET_MM = 12.0
"""Distance of the first and last matching marks from the ends of a seam."""
MARK_HALF_MM = 5.0
"""Half the length of a matching mark's stroke across the seam line."""


@dataclass(frozen=True)
class Seam:
    """The line where two sheets meet.

    Attributes
    ----------
    under, over : str
        Labels of the sheet laid underneath (left or above) and of the sheet cut along the
        line and laid over it (right or below).
    axis : str
        ``"u"``: a vertical line at ``u = at``; ``"v"``: a horizontal line at ``v = at``.
    at : float
        Position of the line, drawing mm.
    span : (float, float)
        Extent along the line that both sheets keep, drawing mm.
    marks : tuple of (float, str)
        Matching marks: position along the line (drawing mm) and letter pair.
    """

    under: str
    over: str
    axis: str
    at: float
    span: tuple[float, float]
    marks: tuple[tuple[float, str], ...]

    def points(self, along: float, across: float = 0.0) -> tuple[float, float]:
        """Drawing ``(u, v)`` of a point ``along`` the line, ``across`` it towards ``over``."""
        if self.axis == "u":
            return self.at + across, along
        return along, self.at - across


def pair_label(index: int) -> str:
    """Letter pair of the ``index``-th matching mark: ``"AA"``, ``"AB"``, ..., ``"ZZ"``."""
    letters = string.ascii_uppercase
    return letters[(index // 26) % 26] + letters[index % 26]


def keep_area(region, col: int, row: int, grid, overlap: float):
    """``(u0, v0, u1, v1)`` drawing mm that a sheet keeps once cut and laid (see above)."""
    cols, rows = grid
    u0, v0, u1, v1 = region
    half = overlap / 2
    return (u0 + half if col > 0 else u0, v0 + half if row < rows - 1 else v0,
            u1 - half if col < cols - 1 else u1, v1 - half if row > 0 else v1)


def _marks_along(lo: float, hi: float, first: int) -> tuple[tuple[float, str], ...]:
    length = hi - lo - 2 * MARK_INSET_MM
    if length <= 0:
        return (((lo + hi) / 2, pair_label(first)),)
    n = max(2, int(length // MARK_SPACING_MM) + 2)
    step = length / (n - 1)
    return tuple((lo + MARK_INSET_MM + i * step, pair_label(first + i)) for i in range(n))


def _clear_of(seam: Seam, clear) -> Seam:
    """``seam`` with each matching mark slid along the line (2 mm at a time, at most three
    quarters of the spacing, never within 12 mm of another mark) to the nearest place where
    the mark and its letters on both sides stay off ``clear`` (the parts, drawing mm); a mark
    with no such place stays."""
    from shapely.geometry import box

    lo, hi = seam.span
    reach = 2 * MARK_HALF_MM + 4.0  # the tick's half-length, the gap, two letters

    def footprint(t):
        (a, b), (c, d) = seam.points(t - 4.0, -reach), seam.points(t + 4.0, reach)
        return box(min(a, c), min(b, d), max(a, c), max(b, d))

    marks = list(seam.marks)
    for i, (t, pair) in enumerate(seam.marks):
        others = [m for j, (m, _) in enumerate(marks) if j != i]
        tries = [t + s * k * 2.0 for k in range(int(0.75 * MARK_SPACING_MM / 2) + 1)
                 for s in (1, -1)]
        free = next((u for u in tries if lo + 4.0 <= u <= hi - 4.0
                     and all(abs(u - m) >= 12.0 for m in others)
                     and not footprint(u).intersects(clear)), t)
        marks[i] = (free, pair)
    return Seam(seam.under, seam.over, seam.axis, seam.at, seam.span, tuple(marks))


def seams_of(sheets, clear=None) -> tuple[Seam, ...]:
    """Every seam of a tiled template: vertical ones row by row, then horizontal ones;
    with ``clear`` (a shapely geometry, drawing mm: the parts), their matching marks slid
    off it where they can be.

    ``sheets`` are :class:`rgmcad.printing.sheets.SheetInfo` with ``keep_mm`` set.
    """
    by_pos = {(s.col, s.row): s for s in sheets}
    out, count = [], 0
    for (c, r), s in sorted(by_pos.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        right = by_pos.get((c + 1, r))
        if right is not None:
            lo, hi = s.keep_mm[1], s.keep_mm[3]
            marks = _marks_along(lo, hi, count)
            count += len(marks)
            out.append(Seam(s.label, right.label, "u", s.keep_mm[2], (lo, hi), marks))
    for (c, r), s in sorted(by_pos.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        below = by_pos.get((c, r + 1))
        if below is not None:
            lo, hi = s.keep_mm[0], s.keep_mm[2]
            marks = _marks_along(lo, hi, count)
            count += len(marks)
            out.append(Seam(s.label, below.label, "v", s.keep_mm[1], (lo, hi), marks))
    return tuple(out) if clear is None else tuple(_clear_of(seam, clear) for seam in out)


def label_keepouts(sheets, seams, tick_strip_mm: float = 6.0):
    """Where labels must not go, and where they must stay, drawing mm (shapely).

    Returns ``(avoid, inside)``: ``avoid`` the seam lines with a margin, their matching
    marks and letter pairs, and the strips along the top and left of each sheet's kept area
    that carry world ticks; ``inside`` the area the sheets keep, less a margin, so no label
    is clipped at a sheet's edge or left in a strip that is cut away.
    """
    from shapely.geometry import LineString
    from shapely.geometry import box as shapely_box
    from shapely.ops import unary_union

    avoid = []
    for s in seams:
        lo, hi = s.span
        avoid.append(LineString([s.points(lo), s.points(hi)]).buffer(1.5))
        reach = MARK_HALF_MM + 7.0
        for t, _ in s.marks:
            a, b = s.points(t - 2.0, -reach), s.points(t + 2.0, reach)
            avoid.append(shapely_box(min(a[0], b[0]), min(a[1], b[1]),
                                     max(a[0], b[0]), max(a[1], b[1])))
    for s in sheets:
        u0, v0, u1, v1 = s.keep_mm
        avoid.append(shapely_box(u0, v1 - tick_strip_mm, u1, v1))
        avoid.append(shapely_box(u0, v0, u0 + 2 * tick_strip_mm, v1))
    inside = unary_union([shapely_box(*s.keep_mm) for s in sheets]).buffer(-1.0)
    return tuple(avoid), inside
