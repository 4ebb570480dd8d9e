"""Text of a template: font metrics, wrapping, and the labels beside the parts.

Text is set in reportlab's standard fonts (Helvetica), whose metrics need no font file;
sizes are millimetres. A part's label block (its order and name, then notes) is placed
beside its outline by a greedy search that avoids outlines and earlier labels.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from shapely.geometry import box as shapely_box

from rgmcad.printing.inputs import PlacedPart

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

NAME_MM = 2.6
"""Font size of a part's name, mm."""
NOTE_MM = 2.0
"""Font size of notes, mm."""


def font_name(bold: bool) -> str:
    """The standard font's name: Helvetica, or Helvetica-Bold."""
    return "Helvetica-Bold" if bold else "Helvetica"


def pdf_safe(text: str) -> str:
    """Text in the standard fonts' encoding (WinAnsi): anything else becomes '?'."""
    return text.encode("cp1252", "replace").decode("cp1252")


def text_width(text: str, size: float, bold: bool = False) -> float:
    """Width in mm of ``text`` set at font size ``size`` mm."""
    from reportlab.pdfbase.pdfmetrics import stringWidth

    return stringWidth(pdf_safe(text), font_name(bold), size)


def wrap(text: str, size: float, width: float, bold: bool = False) -> list[str]:
    """Split ``text`` into lines no wider than ``width`` mm at font size ``size`` mm."""
    lines: list[str] = []
    for word in text.split():
        if lines and text_width(lines[-1] + " " + word, size, bold) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return lines or [""]


def label_lines(part: PlacedPart, notes: list[str]) -> list[tuple[str, float, bool]]:
    """A part's label as ``(text, size mm, bold)`` lines: order and name, notes, tolerances."""
    lines = [(f"{part.order}. {part.name}", NAME_MM, True)]
    lines += [(n, NOTE_MM, False) for n in notes]
    if part.tolerances:
        for chunk in wrap(", ".join(part.tolerances), NOTE_MM, 60.0):
            lines.append((chunk, NOTE_MM, False))
    return lines


def block_size(lines) -> tuple[float, float]:
    """``(width, height)`` in mm of a block of :func:`label_lines`."""
    width = max(text_width(t, s, b) for t, s, b in lines) + 1.0
    height = sum(1.25 * s for _, s, _ in lines) + 1.0
    return width, height


GROWTH_COST = 0.05
"""Cost of a label per mm it widens or heightens the drawing (overlaps cost 1 per mm²): among
free places, one inside the drawing wins; a label out in the margin can cost a sheet."""


def place_labels(outlines, sizes, avoid=(), inside=None) -> list[tuple[float, float, float, float]]:
    """Greedy label placement beside each outline, avoiding outlines and earlier labels.

    Candidates are tried around the outline's bounding box at growing distances, beside each
    side and slid along it; the one that overlaps least wins, ties going to the one that
    grows the drawing least (its extent: every outline and the labels placed so far), then
    to the nearest. ``avoid`` are more areas to keep clear (shapely, e.g. seam lines and
    their marks); a label should lie within ``inside`` (e.g. the area the sheets keep), if
    given.
    """
    obstacles = [o.buffer(1.0) for o in outlines] + list(avoid)
    bounds = [np.array(o.bounds) for o in obstacles]
    boxes: list[tuple[float, float, float, float]] = []
    extent = (np.array([g.bounds for g in outlines]) if outlines else np.zeros((1, 4)))
    ex0, ey0 = extent[:, 0].min(), extent[:, 1].min()
    ex1, ey1 = extent[:, 2].max(), extent[:, 3].max()

    def overlap(b):
        cost = 0.0
        bb = b.bounds
        for g, gb in zip(obstacles, bounds, strict=True):
            if gb[0] < bb[2] and bb[0] < gb[2] and gb[1] < bb[3] and bb[1] < gb[3]:
                cost += b.intersection(g).area
        if inside is not None and not inside.contains(b):
            cost += 4.0 * b.difference(inside).area + 1.0
        for x0, y0, x1, y1 in boxes:
            dx = min(bb[2], x1 + 1.0) - max(bb[0], x0 - 1.0)
            dy = min(bb[3], y1 + 1.0) - max(bb[1], y0 - 1.0)
            if dx > 0 and dy > 0:
                cost += dx * dy
        return cost

    for k, (geom, (w, h)) in enumerate(zip(outlines, sizes, strict=True)):
        bx0, by0, bx1, by1 = geom.bounds
        cy = (by0 + by1) / 2
        cx = (bx0 + bx1) / 2
        cands = []
        for d in (2.0, 6.0, 12.0, 20.0, 35.0, 60.0, 90.0):
            cands += [
                (bx1 + d, cy - h / 2),
                (bx0, by1 + d),
                (bx0, by0 - d - h),
                (bx0 - d - w, cy - h / 2),
                (bx1 + d, by1 - h),
                (bx1 + d, by0),
                (cx - w / 2, by1 + d),
                (cx - w / 2, by0 - d - h),
                (bx0 - d - w, by1 - h),
                (bx0 - d - w, by0),
            ]
            for shift in (-1.0, 1.0, -2.0, 2.0, -3.0, 3.0):  # slid along the side
                cands += [(cx - w / 2 + shift * w / 2, by1 + d),
                          (cx - w / 2 + shift * w / 2, by0 - d - h),
                          (bx1 + d, cy - h / 2 + shift * h),
                          (bx0 - d - w, cy - h / 2 + shift * h)]
        best, best_cost, best_overlap = cands[0], math.inf, 0.0
        for i, (x0, y0) in enumerate(cands):
            growth = (max(ex0 - x0, 0.0) + max(x0 + w - ex1, 0.0)
                      + max(ey0 - y0, 0.0) + max(y0 + h - ey1, 0.0))
            tie = GROWTH_COST * growth + 1e-4 * i
            if tie >= best_cost:
                continue
            cost = overlap(shapely_box(x0, y0, x0 + w, y0 + h))
            if cost + tie < best_cost:
                best, best_cost, best_overlap = (x0, y0), cost + tie, cost
        if best_overlap > 1.0:
            log.info("label %d overlaps other drawing by %.1f mm²", k, best_overlap)
        x0, y0 = best
        boxes.append((x0, y0, x0 + w, y0 + h))
        ex0, ey0, ex1, ey1 = min(ex0, x0), min(ey0, y0), max(ex1, x0 + w), max(ey1, y0 + h)
    return boxes
