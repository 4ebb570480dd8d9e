"""The template's PDF: the first page (assembly map, test squares, legend, parts list), then
the tiled sheets, each with its marks, bands of text, overlap strips and world ticks.

Pages are drawn with reportlab in millimetres, origin at the page's top-left (sheet
coordinates, see :mod:`rgmcad.printing.sheets`); the drawing's items are mapped into each
sheet's window. The parts list runs over onto further pages when long:
:func:`cover_page_count` tells how many pages come before the tiled sheets, so the sheets
can be numbered before anything is written.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rgmcad.printing.drawing import Drawing, TextItem
from rgmcad.printing.labels import font_name, pdf_safe, text_width, wrap
from rgmcad.printing.plane import PlaneFrame
from rgmcad.printing.sheets import (
    BAND_MM,
    MARGIN_MM,
    TAG_SIDE_MM,
    SheetInfo,
    sheet_label,
    tag_quads,
)


class _Pdf:
    """Thin helper over a reportlab canvas, in mm with the origin at the page's top-left."""

    def __init__(self, path: Path, title: str):
        from reportlab.pdfgen import canvas

        self.c = canvas.Canvas(str(path), pageCompression=1)
        self.c.setTitle(title or "rgmcad assembly template")
        self.c.setCreator("rgmcad")
        self.w = self.h = 0.0
        self.pages = 0

    def new_page(self, w: float, h: float):
        from reportlab.lib.units import mm

        if self.pages:
            self.c.showPage()
        self.pages += 1
        self.w, self.h = w, h
        self.c.setPageSize((w * mm, h * mm))
        self.c.scale(mm, mm)  # user units are mm from here on (y up)

    def y(self, y_down: float) -> float:
        return self.h - y_down

    def text(self, x, y_down, text, size, bold=False, anchor="start", colour=(0, 0, 0)):
        c = self.c
        c.setFillColorRGB(*colour)
        c.setFont(font_name(bold), size)
        t = pdf_safe(text)
        if anchor == "middle":
            c.drawCentredString(x, self.y(y_down), t)
        elif anchor == "end":
            c.drawRightString(x, self.y(y_down), t)
        else:
            c.drawString(x, self.y(y_down), t)

    def polyline(self, pts_down, width=0.2, colour=(0, 0, 0), dash=(), closed=False):
        c = self.c
        p = c.beginPath()
        pts = np.asarray(pts_down, float)
        p.moveTo(pts[0, 0], self.y(pts[0, 1]))
        for x, yy in pts[1:]:
            p.lineTo(x, self.y(yy))
        if closed:
            p.close()
        c.setStrokeColorRGB(*colour)
        c.setLineWidth(width)
        c.setDash(list(dash) if dash else [])
        c.drawPath(p, stroke=1, fill=0)
        c.setDash([])

    def rect(self, x, y_down, w, h, fill=None, stroke=(0, 0, 0), width=0.2):
        c = self.c
        if fill is not None:
            c.setFillColorRGB(*fill)
        if stroke is not None:
            c.setStrokeColorRGB(*stroke)
            c.setLineWidth(width)
        c.rect(x, self.y(y_down + h), w, h, stroke=int(stroke is not None),
               fill=int(fill is not None))

    def tag(self, tag_id: int, corners_down: np.ndarray):
        c = self.c
        p = c.beginPath()
        for q in tag_quads(tag_id, corners_down):
            p.moveTo(q[0, 0], self.y(q[0, 1]))
            for x, yy in q[1:]:
                p.lineTo(x, self.y(yy))
            p.close()
        c.setFillColorRGB(0, 0, 0)
        c.drawPath(p, stroke=0, fill=1)

    def drawing(self, items, skip_text=False):
        """Draw items whose coordinates are drawing mm (current transform maps them)."""
        from reportlab.pdfgen.canvas import FILL_EVEN_ODD

        c = self.c
        for it in items:
            if isinstance(it, TextItem):
                if skip_text:
                    continue
                c.setFillColorRGB(*it.colour)
                c.setFont(font_name(it.bold), it.size)
                t = pdf_safe(it.text)
                draw = {"middle": c.drawCentredString, "end": c.drawRightString}.get(
                    it.anchor, c.drawString)
                draw(it.x, it.y, t)
                continue
            p = c.beginPath()
            for ring in it.rings:
                p.moveTo(*ring[0])
                for x, yy in ring[1:]:
                    p.lineTo(x, yy)
                if it.closed:
                    p.close()
            if it.fill is not None:
                c.setFillColorRGB(*it.fill)
            if it.stroke is not None:
                c.setStrokeColorRGB(*it.stroke)
                c.setLineWidth(it.width)
                c.setDash(list(it.dash) if it.dash else [])
            c.drawPath(p, stroke=int(it.stroke is not None), fill=int(it.fill is not None),
                       fillMode=FILL_EVEN_ODD)  # holes stay holes
            c.setDash([])

    def save(self):
        self.c.showPage()
        self.c.save()


def _page_marks(pdf: _Pdf, info: SheetInfo):
    for tid in info.tag_ids:
        pdf.tag(tid, info.tag_corners_mm[tid])


def _scale_bar(pdf: _Pdf, x: float, y_down: float):
    """A 100 mm bar of alternating 10 mm blocks, top-left at (x, y_down)."""
    for i in range(10):
        pdf.rect(x + 10 * i, y_down, 10.0, 2.0, fill=(0, 0, 0) if i % 2 == 0 else (1, 1, 1),
                 stroke=None)
    pdf.rect(x, y_down, 100.0, 2.0, fill=None, width=0.15)
    for i in (0, 50, 100):
        pdf.polyline([[x + i, y_down - 1.0], [x + i, y_down + 2.0]], width=0.15)
        pdf.text(x + i, y_down - 1.6, f"{i}" + (" mm" if i == 100 else ""), 2.2,
                 anchor="middle")


_PRINT_NOTE = "Print at 100 % / actual size \u2014 do not scale"


def _top_band(pdf: _Pdf, label: str, lines: list[str]):
    x0 = MARGIN_MM + TAG_SIDE_MM + 3.0
    x1 = pdf.w - MARGIN_MM - TAG_SIDE_MM - 3.0
    pdf.text(x0, MARGIN_MM + 7.5, label, 8.0, bold=True)
    lx = x0 + text_width(label, 8.0, True) + 4.0
    y = MARGIN_MM + 3.5
    for i, line in enumerate(lines[:5]):
        size = 2.6 if i == 0 else 2.2
        while text_width(line, size, i == 0) > x1 - lx and len(line) > 4:
            line = line[:-2]
        pdf.text(lx, y, line, size, bold=(i == 0))
        y += 1.35 * size + 0.2


def _bottom_band(pdf: _Pdf, text: str):
    x0 = MARGIN_MM + TAG_SIDE_MM + 5.0
    y_bar = pdf.h - MARGIN_MM - BAND_MM + 8.0
    _scale_bar(pdf, x0, y_bar)
    pdf.text(x0, y_bar + 6.5, "scale bar: 100 mm", 2.0)
    room = pdf.w - MARGIN_MM - TAG_SIDE_MM - 3.0 - (x0 + 104.0)
    for i, chunk in enumerate(wrap(text, 2.0, room)[:4]):
        pdf.text(x0 + 104.0, y_bar + 1.0 + 2.8 * i, chunk, 2.0)


def _world_ticks(pdf: _Pdf, info: SheetInfo, frame: PlaneFrame):
    """World coordinates along the window's top and left edges.

    A tick every 10 mm, a label (e.g. ``x -150``) every 50 mm, for drawing axes that run
    along a world axis; they place the sheet on the floor or board.
    """
    x0, y0, _, _ = info.window_mm
    u0, v0, u1, v1 = info.region_mm
    grey = (0.45, 0.45, 0.45)
    for axis, along in ((frame.u_axis, "u"), (frame.v_axis, "v")):
        i = int(np.argmax(np.abs(axis)))
        if abs(axis[i]) < 0.999:
            continue
        sign, name, o = float(np.sign(axis[i])), "xyz"[i], 1000.0 * float(frame.origin[i])
        lo, hi = (u0, u1) if along == "u" else (v0, v1)
        wa, wb = sorted((o + sign * lo, o + sign * hi))
        for w in range(int(math.ceil(wa / 10.0)) * 10, int(math.floor(wb / 10.0)) * 10 + 1, 10):
            d = (w - o) * sign
            major = w % 50 == 0
            tick = 3.0 if major else 1.5
            if along == "u":
                x = x0 + (d - u0)
                pdf.polyline([[x, y0], [x, y0 + tick]], 0.15, grey)
                if major:
                    pdf.text(x + 0.6, y0 + 3.2, f"{name} {w}", 1.8, colour=grey)
            else:
                y = y0 + (v1 - d)
                pdf.polyline([[x0, y], [x0 + tick, y]], 0.15, grey)
                if major:
                    pdf.text(x0 + 3.6, y + 0.6, f"{name} {w}", 1.8, colour=grey)


def _tile_pages(pdf, drawing, result_sheets, grid, title, overlap, paper, frame):
    cols, rows = grid
    for info in result_sheets:
        w, h = info.size_mm
        pdf.new_page(w, h)
        c = pdf.c
        x0, y0, x1, y1 = info.window_mm
        u0, v0, u1, v1 = info.region_mm
        c.saveState()
        p = c.beginPath()
        p.rect(x0, h - y1, x1 - x0, y1 - y0)
        c.clipPath(p, stroke=0, fill=0)
        c.translate(x0 - u0, (h - y1) - v0)
        pdf.drawing(drawing.items)
        c.restoreState()
        # overlap strips: cut at left/top, align the neighbour's cut edge at right/bottom
        dash_cut, dash_align = (3.0, 1.5), (0.8, 1.2)
        if info.col > 0:
            pdf.polyline([[x0 + overlap, y0], [x0 + overlap, y1]], 0.25, dash=dash_cut)
            pdf.text(x0 + overlap + 1.0, y0 + 3.0, "cut", 2.0)
        if info.row > 0:
            pdf.polyline([[x0, y0 + overlap], [x1, y0 + overlap]], 0.25, dash=dash_cut)
            pdf.text(x1 - 1.0, y0 + overlap - 1.0, "cut", 2.0, anchor="end")
        if info.col < cols - 1:
            pdf.polyline([[x1 - overlap, y0], [x1 - overlap, y1]], 0.2, (0.4, 0.4, 0.4),
                         dash_align)
        if info.row < rows - 1:
            pdf.polyline([[x0, y1 - overlap], [x1, y1 - overlap]], 0.2, (0.4, 0.4, 0.4),
                         dash_align)
        pdf.rect(x0, y0, x1 - x0, y1 - y0, fill=None, stroke=(0.6, 0.6, 0.6), width=0.1)
        _world_ticks(pdf, info, frame)
        _page_marks(pdf, info)
        neigh = []
        for name, dc, dr in (("left", -1, 0), ("right", 1, 0), ("above", 0, -1),
                             ("below", 0, 1)):
            cc, rr = info.col + dc, info.row + dr
            if 0 <= cc < cols and 0 <= rr < rows:
                neigh.append(f"{name} {sheet_label(cc, rr)}")
        _top_band(pdf, info.label, [
            _PRINT_NOTE,
            f"{title}  -  sheet {info.label} of {cols} x {rows} ({paper} {info.orientation})",
            "neighbours: " + (", ".join(neigh) or "none"),
            "cut along the dashed lines at left/top; lay the cut edge on the neighbour's "
            "dotted line",
        ])
        ids = info.tag_ids
        _bottom_band(pdf, f"page {info.page}; "
                     f"marks {ids[0]}-{ids[-1]} (AprilTag 36h11) let 'rgmcad verify-print' "
                     "check the scale; do not cover them")


# first page: y of the assembly map's box and its height, of the test squares, of the parts list
_MAP_Y, _MAP_H = MARGIN_MM + BAND_MM + 5.0, 68.0
_SQUARES_Y = _MAP_Y + _MAP_H + 6.0
_PARTS_Y = _SQUARES_Y + 100.0 + 7.0


def _parts_list(parts, size_mm) -> list[list[tuple[float, str]]]:
    """The parts list's lines as ``(y, text)`` sheet mm, per page: the first page's, then
    those of each continuation page."""
    w, h = size_mm
    rows_text = []
    for p in parts:
        notes = "; ".join([*p.notes, *p.tolerances])
        for i, chunk in enumerate(wrap(f"{p.order}. {p.name}: {notes}", 2.2,
                                       w - 2 * MARGIN_MM - 6.0)):
            rows_text.append(chunk if i == 0 else "    " + chunk)
    pages: list[list[tuple[float, str]]] = [[]]
    y, y_bottom = _PARTS_Y + 4.0, h - MARGIN_MM - BAND_MM
    for text in rows_text:
        if y > y_bottom - 2.0:
            pages.append([])
            y, y_bottom = MARGIN_MM + 10.0, h - MARGIN_MM
        pages[-1].append((y, text))
        y += 3.0
    return pages


def cover_page_count(parts, size_mm) -> int:
    """Pages before the tiled sheets: the first page and the parts list's continuations.

    ``parts`` are :class:`rgmcad.printing.drawing.PartOutline`; ``size_mm`` the first
    page's ``(width, height)``.
    """
    return len(_parts_list(parts, size_mm))


def _cover_pages(pdf, drawing, parts, info: SheetInfo, sheets, grid, title, frame, paper,
                 orientation, overlap):
    w, h = info.size_mm
    pdf.new_page(w, h)
    _page_marks(pdf, info)
    cols, rows = grid
    view = {"floor": "laid on the floor, seen from above",
            "board": "taped to the board, seen from the front (the parts' side)"}.get(
        frame.kind, f"plane {frame.kind}, seen from the side its normal points to")
    _top_band(pdf, "map", [
        f"{title} - assembly template (rgmcad)",
        _PRINT_NOTE,
        f"{cols} x {rows} sheets of {paper} {orientation} + this page; drawing at 1:1, {view}",
        f"overlap {overlap:.0f} mm; check the test squares with a ruler before cutting",
    ])
    _bottom_band(pdf, f"first page; marks {info.tag_ids[0]}-{info.tag_ids[-1]} (AprilTag "
                      "36h11) let 'rgmcad verify-print' check the printer's scale")
    x0, y_top = MARGIN_MM, MARGIN_MM + BAND_MM
    ww = w - 2 * MARGIN_MM

    # assembly map
    pdf.text(x0, y_top + 3.0, "Assembly map", 3.0, bold=True)
    box_y, box_h = _MAP_Y, _MAP_H
    u0 = min(s.region_mm[0] for s in sheets)
    v1 = max(s.region_mm[3] for s in sheets)
    u1 = max(s.region_mm[2] for s in sheets)
    v0 = min(s.region_mm[1] for s in sheets)
    k = min(ww / (u1 - u0), box_h / (v1 - v0))
    ox = x0 + (ww - k * (u1 - u0)) / 2
    c = pdf.c
    c.saveState()
    c.translate(ox - k * u0, pdf.y(box_y) - k * v1)
    c.scale(k, k)
    pdf.drawing(drawing.minimap, skip_text=True)
    c.restoreState()
    for s in sheets:
        su0, sv0, su1, sv1 = s.region_mm
        last_c, last_r = s.col == cols - 1, s.row == rows - 1
        cu1 = su1 if last_c else su1 - overlap
        cv0 = sv0 if last_r else sv0 + overlap
        rx, ry = ox + k * (su0 - u0), box_y + k * (v1 - sv1)
        pdf.rect(rx, ry, k * (cu1 - su0), k * (sv1 - cv0), fill=None, stroke=(0.2, 0.2, 0.8),
                 width=0.25)
        pdf.text(rx + k * (cu1 - su0) / 2, ry + k * (sv1 - cv0) / 2 + 1.5, s.label, 4.0,
                 bold=True, anchor="middle", colour=(0.2, 0.2, 0.8))

    # test squares and legend
    sq_y = _SQUARES_Y
    pdf.text(x0, sq_y - 1.5, "Test square: 100 mm (measure before cutting)", 2.4, bold=True)
    pdf.rect(x0, sq_y, 100.0, 100.0, fill=None, width=0.3)
    pdf.text(x0 + 50.0, sq_y + 52.0, "100 mm x 100 mm", 3.0, anchor="middle")
    pdf.text(x0 + 50.0, sq_y + 57.0, "if not, reprint at 100 % / actual size", 2.2,
             anchor="middle")
    lx = x0 + 106.0
    pdf.rect(lx, sq_y, 25.4, 25.4, fill=None, width=0.3)
    pdf.text(lx + 12.7, sq_y + 13.5, "1 inch", 2.6, anchor="middle")
    legend = [
        ("Legend", True),
        ("coloured outline: the part's silhouette at 1:1", False),
        ("'3. name': placement order and part name", False),
        ("bottom/back, origin: height of the part's lowest point and of its frame "
         "origin above the plane", False),
        ("tilt: angle the outline cannot show", False),
        ("dash-dot line: a base plane (floor, board) seen edge-on", False),
        ("dashed line: cut here; dotted line: lay the next sheet's cut edge here", False),
        ("grey ticks along a sheet's top and left edges: world coordinates in mm "
         "(e.g. 'x 150'), to place the sheets", False),
        ("black squares in the corners: marks for verify-print; keep them", False),
    ]
    ly = sq_y + 30.0
    for text, bold in legend:
        for chunk in wrap(text, 2.2, w - MARGIN_MM - lx, bold):
            if ly > sq_y + 100.0:
                break
            pdf.text(lx, ly, chunk, 2.2, bold=bold)
            ly += 2.9

    # parts list, continued on further pages when long
    pdf.text(x0, _PARTS_Y, "Parts, in placement order", 2.8, bold=True)
    for i, lines in enumerate(_parts_list(parts, (w, h))):
        if i:
            pdf.new_page(w, h)
            pdf.text(x0, MARGIN_MM + 5.0, f"{title} - parts, continued", 2.8, bold=True)
        for y, text in lines:
            pdf.text(x0, y, text, 2.2, bold=False)


def write_pdf(path: Path, title: str, drawing: Drawing, parts, frame: PlaneFrame,
              map_sheet: SheetInfo, sheets: tuple[SheetInfo, ...], grid: tuple[int, int],
              paper: str, orientation: str, overlap_mm: float) -> int:
    """Write the template's PDF; returns its number of pages.

    ``parts`` are the drawing's :class:`rgmcad.printing.drawing.PartOutline` in placement
    order; ``sheets`` the tiled sheets, numbered after :func:`cover_page_count` pages.
    """
    pdf = _Pdf(path, title)
    _cover_pages(pdf, drawing, parts, map_sheet, sheets, grid, title, frame, paper,
                 orientation, overlap_mm)
    _tile_pages(pdf, drawing, sheets, grid, title, overlap_mm, paper, frame)
    pdf.save()
    return pdf.pages
