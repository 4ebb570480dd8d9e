"""A tiled sheet of the template's PDF: its part of the drawing, its seams (cut and butt
lines, matching marks, the strip that goes under the neighbour), world ticks in the area it
keeps, its marks, and its bands of instructions.

Drawn on the helper canvas of :mod:`rgmcad.printing.pdf` (mm, origin top-left, y down).
"""

from __future__ import annotations

import math

import numpy as np

from rgmcad.printing.labels import font_name, text_width, wrap
from rgmcad.printing.plane import PlaneFrame
from rgmcad.printing.seams import MARK_HALF_MM, Seam
from rgmcad.printing.sheets import BAND_MM, MARGIN_MM, TAG_SIDE_MM, SheetInfo

SEAM_RGB = (0.85, 0.0, 0.55)
"""Colour of seam lines and matching marks (magenta: no part is filled with it)."""
SEAM_WIDTH_MM = 0.3
UNDER_RGB = (0.55, 0.55, 0.55)
"""Colour of the hatching on the strip that goes under a neighbour."""
PRINT_NOTE = "Print at 100 % / actual size \u2014 do not scale"


def axis_name(direction) -> str:
    """World axis a drawing direction runs along (``"+x"``, ``"-z"``), or ``""``."""
    d = np.asarray(direction, float)
    i = int(np.argmax(np.abs(d)))
    return ("+" if d[i] > 0 else "-") + "xyz"[i] if abs(d[i]) > 0.999 else ""


def top_band(pdf, label: str, lines: list[str]):
    """The sheet's label and up to six wrapped lines of text beside it, in the top band."""
    x0 = MARGIN_MM + TAG_SIDE_MM + 3.0
    x1 = pdf.w - MARGIN_MM - TAG_SIDE_MM - 3.0
    pdf.text(x0, MARGIN_MM + 7.5, label, 8.0, bold=True)
    lx = x0 + text_width(label, 8.0, True) + 4.0
    y, n = MARGIN_MM + 3.5, 0
    for i, line in enumerate(lines):
        size = 2.6 if i == 0 else 2.2
        for chunk in wrap(line, size, x1 - lx, i == 0):
            if n == 6:
                return
            pdf.text(lx, y, chunk, size, bold=(i == 0))
            y += 1.35 * size + 0.2
            n += 1


def scale_bar(pdf, x: float, y_down: float):
    """A 100 mm bar of alternating 10 mm blocks, top-left at (x, y_down)."""
    for i in range(10):
        pdf.rect(x + 10 * i, y_down, 10.0, 2.0, fill=(0, 0, 0) if i % 2 == 0 else (1, 1, 1),
                 stroke=None)
    pdf.rect(x, y_down, 100.0, 2.0, fill=None, width=0.15)
    for i in (0, 50, 100):
        pdf.polyline([[x + i, y_down - 1.0], [x + i, y_down + 2.0]], width=0.15)
        pdf.text(x + i, y_down - 1.6, f"{i}" + (" mm" if i == 100 else ""), 2.2,
                 anchor="middle")


def _arrow(pdf, tail, tip, width=0.3):
    tail, tip = np.asarray(tail, float), np.asarray(tip, float)
    d = (tip - tail) / np.linalg.norm(tip - tail)
    side = np.array([-d[1], d[0]])
    pdf.polyline([tail, tip - 1.2 * d], width)
    head = [tip, tip - 2.0 * d + 0.9 * side, tip - 2.0 * d - 0.9 * side]
    pdf.c.setFillColorRGB(0, 0, 0)
    p = pdf.c.beginPath()
    p.moveTo(head[0][0], pdf.y(head[0][1]))
    for x, y in head[1:]:
        p.lineTo(x, pdf.y(y))
    p.close()
    pdf.c.drawPath(p, stroke=0, fill=1)


def page_axes(frame: PlaneFrame) -> tuple[str, str]:
    """The world axes along the page's right and up (``"+x"``, ``"+y"``), or ``"u"``,
    ``"v"`` where the plane is not aligned with them."""
    return axis_name(frame.u_axis) or "u", axis_name(frame.v_axis) or "v"


def orientation_arrows(pdf, x: float, y_down: float, frame: PlaneFrame):
    """Arrows along the page's right and up, named by the world axes they run along."""
    u, v = page_axes(frame)
    _arrow(pdf, (x, y_down), (x + 12.0, y_down))
    _arrow(pdf, (x, y_down), (x, y_down - 12.0))
    pdf.text(x + 13.0, y_down + 0.8, f"world {u}", 2.2, bold=True)
    pdf.text(x + 1.2, y_down - 10.5, f"world {v}", 2.2, bold=True)
    pdf.text(x, y_down + 4.0, "this way up", 2.0)


def bottom_band(pdf, text: str, frame: PlaneFrame | None):
    x0 = MARGIN_MM + TAG_SIDE_MM + 5.0
    y_bar = pdf.h - MARGIN_MM - BAND_MM + 8.0
    scale_bar(pdf, x0, y_bar)
    x_arrows = pdf.w - MARGIN_MM - TAG_SIDE_MM - 30.0
    for i, chunk in enumerate(wrap(text, 2.0, x_arrows - 4.0 - x0)[:3]):
        pdf.text(x0, y_bar + 5.5 + 2.7 * i, chunk, 2.0)
    if frame is not None:
        orientation_arrows(pdf, x_arrows, y_bar + 7.5, frame)


def _world_ticks(pdf, info: SheetInfo, frame: PlaneFrame, clear=None):
    """World coordinates along the top and left edges of the area the sheet keeps.

    A tick every 10 mm, a label (e.g. ``x -150``) every 50 mm, for drawing axes that run
    along a world axis; they place the assembled sheets on the floor or board. A label that
    would lie on ``clear`` (the parts, drawing mm) is left out; its tick stays.
    """
    from shapely.geometry import box

    def label(x, y, text):  # left end of the baseline, sheet mm
        (a, b), (c, d) = info.to_drawing(x, y + 0.4), info.to_drawing(
            x + text_width(text, 1.8, False), y - 1.8)
        if clear is None or not box(min(a, c), min(b, d), max(a, c), max(b, d)).intersects(
                clear):
            pdf.text(x, y, text, 1.8, colour=grey)

    k0, k1 = info.keep_mm[0], info.keep_mm[3]  # left and top edges kept, drawing mm
    x_left, y_top = info.to_page(k0, k1)
    u0, v0, u1, v1 = info.keep_mm
    grey = (0.4, 0.4, 0.4)
    for axis, along in ((frame.u_axis, "u"), (frame.v_axis, "v")):
        i = int(np.argmax(np.abs(axis)))
        if abs(axis[i]) < 0.999:
            continue
        sign, name, o = float(np.sign(axis[i])), "xyz"[i], 1000.0 * float(frame.origin[i])
        lo, hi = (u0 + 1.0, u1 - 8.0) if along == "u" else (v0 + 4.0, v1 - 8.0)
        wa, wb = sorted((o + sign * lo, o + sign * hi))
        for w in range(int(math.ceil(wa / 10.0)) * 10, int(math.floor(wb / 10.0)) * 10 + 1, 10):
            d = (w - o) * sign
            major = w % 50 == 0
            tick = 3.0 if major else 1.5
            if along == "u":
                x = info.to_page(d, v1)[0]
                pdf.polyline([[x, y_top], [x, y_top + tick]], 0.15, grey)
                if major:
                    label(x + 0.6, y_top + 3.2, f"{name} {w}")
            else:
                y = info.to_page(u0, d)[1]
                pdf.polyline([[x_left, y], [x_left + tick, y]], 0.15, grey)
                if major:
                    label(x_left + 3.6, y + 0.6, f"{name} {w}")


def _hatch(pdf, x0, y0, x1, y1, step=2.5):
    """Diagonal hatching of a rectangle (sheet mm), clipped to it."""
    c = pdf.c
    c.saveState()
    p = c.beginPath()
    p.rect(x0, pdf.y(y1), x1 - x0, y1 - y0)
    c.clipPath(p, stroke=0, fill=0)
    span = (x1 - x0) + (y1 - y0)
    for t in np.arange(0.0, span + step, step):
        pdf.polyline([[x0 + t, y0], [x0 + t - (y1 - y0), y1]], 0.12, UNDER_RGB)
    c.restoreState()


def _seam(pdf, info: SheetInfo, seam: Seam):
    """A seam seen from ``info``: the line, its matching marks, and what to do there."""
    over = seam.over == info.label
    lo, hi = seam.span
    ends = [info.to_page(*seam.points(t)) for t in (lo, hi)]
    # the strip beyond the line: cut away (over) or under the neighbour (under)
    x0, y0, x1, y1 = info.window_mm
    if seam.axis == "u":
        x = ends[0][0]
        strip = (x0, y0, x, y1) if over else (x, y0, x1, y1)
    else:
        y = ends[0][1]
        strip = (x0, y0, x1, y) if over else (x0, y, x1, y1)
    if not over:
        _hatch(pdf, *strip)
    a = [info.to_page(*seam.points(t)) for t in (lo - 40.0, hi + 40.0)]  # to the paper's end
    pdf.polyline(a, SEAM_WIDTH_MM, SEAM_RGB)
    keep_side = 1.0 if over else -1.0  # "across" points towards the over sheet
    for t, pair in seam.marks:
        p, q = (info.to_page(*seam.points(t, s * MARK_HALF_MM)) for s in (-1.0, 1.0))
        pdf.polyline([p, q], SEAM_WIDTH_MM, SEAM_RGB)
        lx, ly = info.to_page(*seam.points(t, keep_side * (MARK_HALF_MM + 0.8)))
        if seam.axis == "u":
            pdf.text(lx, ly + 1.0, pair, 2.6, bold=True, colour=SEAM_RGB,
                     anchor="start" if over else "end")
        else:
            pdf.text(lx + 0.8, ly + (2.8 if over else -0.8), pair, 2.6, bold=True,
                     colour=SEAM_RGB)
    # what to do, written in the strip (cut away, or covered by the neighbour)
    sx0, sy0, sx1, sy1 = strip
    text = (f"cut off: {seam.under} shows this" if over
            else f"under {seam.over}: lay its cut edge on this line")
    size = 2.2
    if seam.axis == "u":
        cx, cy = (sx0 + sx1) / 2, (sy0 + sy1) / 2
        pdf.c.saveState()
        pdf.c.translate(cx + 0.8, pdf.y(cy))
        pdf.c.rotate(90)
        pdf.c.setFillColorRGB(0.3, 0.3, 0.3)
        pdf.c.setFont(font_name(False), size)
        pdf.c.drawCentredString(0.0, 0.0, text)
        pdf.c.restoreState()
    else:
        pdf.text((sx0 + sx1) / 2, (sy0 + sy1) / 2 + 0.8, text, size, anchor="middle",
                 colour=(0.3, 0.3, 0.3))


EMPTY_NOTE = "Nothing to place on this sheet: it only holds its neighbours in line."


def tile_page(pdf, drawing, info: SheetInfo, seams, grid, title, paper, frame: PlaneFrame,
              empty: bool = False, clear=None):
    """Draw one tiled sheet on a new page of ``pdf``; ``empty``: no part or rope shows on it,
    and the sheet says so; ``clear``: the parts (drawing mm), which tick labels keep off."""
    cols, rows = grid
    w, h = info.size_mm
    pdf.new_page(w, h)
    c = pdf.c
    x0, y0, x1, y1 = info.window_mm
    u0, v0, _, _ = info.region_mm
    c.saveState()
    p = c.beginPath()
    p.rect(x0, h - y1, x1 - x0, y1 - y0)
    c.clipPath(p, stroke=0, fill=0)
    c.translate(x0 - u0, (h - y1) - v0)
    pdf.drawing(drawing.items, region=info.region_mm)
    c.restoreState()
    pdf.rect(x0, y0, x1 - x0, y1 - y0, fill=None, stroke=(0.6, 0.6, 0.6), width=0.1)
    mine = [s for s in seams if info.label in (s.under, s.over)]
    c.saveState()
    p = c.beginPath()
    p.rect(x0, h - y1, x1 - x0, y1 - y0)
    c.clipPath(p, stroke=0, fill=0)
    for seam in mine:
        _seam(pdf, info, seam)
    c.restoreState()
    _world_ticks(pdf, info, frame, clear)
    for tid in info.tag_ids:
        pdf.tag(tid, info.tag_corners_mm[tid])
    cut = [s.under for s in mine if s.over == info.label]
    under = [s.over for s in mine if s.under == info.label]
    steps = []
    if cut:
        sides = [n for n, a in (("left", "u"), ("top", "v"))
                 if any(x.over == info.label and x.axis == a for x in mine)]
        steps.append(f"Cut along the magenta line at the {' and '.join(sides)}; lay this sheet on "
                     f"{' and '.join(cut)}, the cut edge on their magenta line and each letter "
                     "pair on its twin (AB on AB); tape across the seam.")
    if under:
        steps.append(f"{' and '.join(under)} {'go' if len(under) > 1 else 'goes'} on the "
                     "hatched strip, over this sheet.")
    top_band(pdf, info.label, [
        PRINT_NOTE,
        f"{title}  -  sheet {info.label} of {cols} x {rows} ({paper} {info.orientation})",
        *steps,
        *([EMPTY_NOTE] if empty else []),  # last: the band holds six lines
    ])
    ids = info.tag_ids
    bottom_band(pdf, f"scale bar: 100 mm; page {info.page}; marks {ids[0]}-{ids[-1]} "
                "(AprilTag 36h11) let 'rgmcad verify-print' check the scale: keep them",
                frame)
