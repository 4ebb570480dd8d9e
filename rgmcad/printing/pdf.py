"""The template's PDF: the first page (assembly map, test squares, legend, parts list), then
the tiled sheets, each with its marks, bands of text, overlap strips and world ticks.

Pages are drawn with reportlab in millimetres, origin at the page's top-left (sheet
coordinates, see :mod:`rgmcad.printing.sheets`); the drawing's items are mapped into each
sheet's window. The parts list runs over onto further pages when long:
:func:`cover_page_count` tells how many pages come before the tiled sheets, so the sheets
can be numbered before anything is written.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rgmcad.files import naming
from rgmcad.printing.drawing import Drawing, TextItem
from rgmcad.printing.labels import font_name, pdf_safe, text_width, wrap
from rgmcad.printing.making_pages import draw_making_pages
from rgmcad.printing.plane import PlaneFrame
from rgmcad.printing.ropes import rope_rows
from rgmcad.printing.seams import seams_of
from rgmcad.printing.sheetpage import (
    PRINT_NOTE,
    bottom_band,
    orientation_arrows,
    page_axes,
    tile_page,
    top_band,
)
from rgmcad.printing.sheets import BAND_MM, MARGIN_MM, SheetInfo, tag_quads


def _reaches(item, region) -> bool:
    u0, v0, u1, v1 = region
    if isinstance(item, TextItem):
        w = text_width(item.text, item.size, item.bold)
        x0 = item.x - {"middle": w / 2, "end": w}.get(item.anchor, 0.0)
        box = (x0, item.y - item.size, x0 + w, item.y + item.size)
    else:
        pts = np.concatenate(item.rings)
        box = (*pts.min(0), *pts.max(0))
    return box[0] <= u1 and box[2] >= u0 and box[1] <= v1 and box[3] >= v0


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

    def drawing(self, items, skip_text=False, region=None):
        """Draw items whose coordinates are drawing mm (current transform maps them); with
        ``region`` ``(u0, v0, u1, v1)``, only those that reach into it."""
        from reportlab.pdfgen.canvas import FILL_EVEN_ODD

        c = self.c
        for it in items:
            if region is not None and not _reaches(it, region):
                continue
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


def _frame_square(pdf, x, y_down, side, band):
    """A square ``side`` mm across its outer edges, drawn as a filled band ``band`` wide."""
    from reportlab.pdfgen.canvas import FILL_EVEN_ODD

    c = pdf.c
    p = c.beginPath()
    p.rect(x, pdf.y(y_down + side), side, side)
    p.rect(x + band, pdf.y(y_down + side - band), side - 2 * band, side - 2 * band)
    c.setFillColorRGB(0.25, 0.25, 0.25)
    c.drawPath(p, stroke=0, fill=1, fillMode=FILL_EVEN_ODD)  # the inside stays white


# first page: y of the assembly map's box and its height, of the test squares, of the parts list
_MAP_Y, _MAP_H = MARGIN_MM + BAND_MM + 5.0, 68.0
_SQUARES_Y = _MAP_Y + _MAP_H + 6.0
_PARTS_Y = _SQUARES_Y + 100.0 + 7.0


def part_sheets(part, sheets) -> list[str]:
    """Labels of the sheets whose kept area shows some of a part's outline."""
    from shapely.geometry import box

    return [s.label for s in sheets if part.outline.intersects(box(*s.keep_mm))]


def empty_sheets(parts, sheets, ropes=()) -> set[str]:
    """Labels of the sheets whose kept area shows no part's outline and no rope: nothing is
    placed on them, they only hold their neighbours in line."""
    from shapely.geometry import box

    return {s.label for s in sheets
            if not any(o.outline.intersects(box(*s.keep_mm)) for o in [*parts, *ropes])}


def _part_rows(parts, sheets, width: float) -> list[str]:
    """Order, name, sheets and tolerances of each part (the rest is beside its outline)."""
    rows = []
    for p in parts:
        on = part_sheets(p, sheets)
        where = f" [sheet {', '.join(on)}]" if on else ""
        tol = f": {'; '.join(p.tolerances)}" if p.tolerances else ""
        for i, chunk in enumerate(wrap(f"{p.order}. {p.name}{where}{tol}", 2.2, width)):
            rows.append(chunk if i == 0 else "    " + chunk)
    return rows


def _parts_list(parts, size_mm, sheets=(), ropes=()) -> list[list[tuple[float, float, str]]]:
    """The parts list's lines as ``(x, y, text)`` sheet mm, per page: the first page's, then
    those of each continuation page; in as few columns (up to three) as give the fewest
    pages. The ropes (:class:`~rgmcad.printing.ropes.RopeOutline`) come last."""
    w, h = size_mm
    best = None
    for ncol in (1, 2, 3):
        col_w = (w - 2 * MARGIN_MM - 4.0 * (ncol - 1)) / ncol
        pages: list[list[tuple[float, float, str]]] = [[]]
        col, y, y_top, y_bottom = 0, _PARTS_Y + 4.0, _PARTS_Y + 4.0, h - MARGIN_MM - BAND_MM
        for text in _part_rows(parts, sheets, col_w - 6.0) + _rope_rows(ropes, sheets,
                                                                       col_w - 6.0):
            if y > y_bottom - 2.0:
                col += 1
                y = y_top
                if col == ncol:
                    pages.append([])
                    col, y_top, y_bottom = 0, MARGIN_MM + 10.0, h - MARGIN_MM
                    y = y_top
            pages[-1].append((MARGIN_MM + col * (col_w + 4.0), y, text))
            y += 3.0
        if best is None or len(pages) < len(best):
            best = pages
    return best


def _rope_rows(ropes, sheets, width: float) -> list[str]:
    rows = []
    for text in rope_rows(ropes, sheets):
        rows += [chunk if i == 0 else "    " + chunk
                 for i, chunk in enumerate(wrap(text, 2.2, width))]
    return rows


def cover_page_count(parts, size_mm, sheets=(), ropes=()) -> int:
    """Pages before the tiled sheets: the first page and the parts list's continuations.

    ``parts`` are :class:`rgmcad.printing.drawing.PartOutline`; ``size_mm`` the first
    page's ``(width, height)``; ``sheets`` the tiled sheets (the list names each part's);
    ``ropes`` the drawing's ropes (listed after the parts).
    """
    return len(_parts_list(parts, size_mm, sheets, ropes))


def _cover_pages(pdf, drawing, parts, info: SheetInfo, sheets, grid, title, frame, paper,
                 orientation, overlap, empty: set[str], note: str = ""):
    w, h = info.size_mm
    pdf.new_page(w, h)
    _page_marks(pdf, info)
    cols, rows = grid
    view = {"floor": "laid on the floor, seen from above",
            "board": "taped to the board, seen from the front (the parts' side)"}.get(
        frame.kind, f"plane {frame.kind}, seen from the side its normal points to")
    top_band(pdf, "map", [
        f"{title} - assembly template (rgmcad)",
        PRINT_NOTE,
        f"{cols} x {rows} sheets of {paper} {orientation} + this page; drawing at 1:1, {view}",
        f"neighbouring sheets overlap {overlap:.0f} mm and meet on a magenta seam line; "
        "check the test square with a ruler before cutting",
    ])
    bottom_band(pdf, f"scale bar: 100 mm; first page; marks {info.tag_ids[0]}-"
                f"{info.tag_ids[-1]} (AprilTag 36h11) let 'rgmcad verify-print' check the "
                "printer's scale", None)
    x0, y_top = MARGIN_MM, MARGIN_MM + BAND_MM
    ww = w - 2 * MARGIN_MM

    # assembly map
    pdf.text(x0, y_top + 3.0, "Assembly map", 3.0, bold=True)
    if note:
        lx = x0 + text_width("Assembly map", 3.0, True) + 4.0
        pdf.text(lx, y_top + 3.0, wrap(note, 2.4, x0 + ww - lx, False)[0], 2.4)
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
    for s in sheets:  # what each sheet keeps once cut and laid
        su0, sv0, su1, sv1 = s.keep_mm
        rx, ry = ox + k * (su0 - u0), box_y + k * (v1 - sv1)
        pdf.rect(rx, ry, k * (su1 - su0), k * (sv1 - sv0), fill=None, stroke=(0.2, 0.2, 0.8),
                 width=0.25)
        colour = (0.55, 0.55, 0.55) if s.label in empty else (0.2, 0.2, 0.8)
        pdf.text(rx + k * (su1 - su0) / 2, ry + k * (sv1 - sv0) / 2 + 1.5, s.label, 4.0,
                 bold=True, anchor="middle", colour=colour)
        if s.label in empty:
            pdf.text(rx + k * (su1 - su0) / 2, ry + k * (sv1 - sv0) / 2 + 4.5, "(empty)", 2.4,
                     anchor="middle", colour=colour)

    # test squares and legend
    sq_y = _SQUARES_Y
    pdf.text(x0, sq_y - 1.5, "Test square: measure its OUTER edges before cutting", 2.4,
             bold=True)
    _frame_square(pdf, x0, sq_y, 100.0, 4.0)
    pdf.text(x0 + 50.0, sq_y + 48.0, "outer edge to outer edge:", 2.6, anchor="middle")
    pdf.text(x0 + 50.0, sq_y + 53.0, "100 mm x 100 mm", 3.4, bold=True, anchor="middle")
    pdf.text(x0 + 50.0, sq_y + 58.0, "if not, reprint at 100 % / actual size", 2.2,
             anchor="middle")
    lx = x0 + 106.0
    _frame_square(pdf, lx, sq_y, 25.4, 2.0)
    pdf.text(lx + 12.7, sq_y + 12.0, "1 inch", 2.6, anchor="middle")
    pdf.text(lx + 12.7, sq_y + 15.5, "outer edge", 1.8, anchor="middle")
    orientation_arrows(pdf, lx + 40.0, sq_y + 16.0, frame)
    legend = [
        ("Legend", True),
        ("coloured outline: the part's silhouette at 1:1", False),
        ("'3. name': placement order and part name", False),
        ("bottom/back, origin: height of the part's lowest point and of its frame "
         "origin above the plane", False),
        ("tilt: angle the outline cannot show, and which way the part leans (dashed "
         "arrow); solid arrow: the way a domino falls", False),
        ("frame (circle and cross): a run's or joint's origin, with its tolerances; moving "
         "or turning the frame moves all its parts", False),
        ("dash-dot line: a base plane (floor, board) seen edge-on", False),
        ("dark red line: a rope's path, circles at its hooks and pulleys; cut it to the "
         "length in its label and the parts list", False),
        ("magenta line: a seam. On the sheet to the right or below, cut along it; lay that "
         "cut edge on the same line of the sheet to the left or above (its hatched strip "
         "goes under), letter pairs meeting (AB on AB); tape across", False),
        ("grey ticks along the top and left of what a sheet keeps: world coordinates in mm "
         "(e.g. 'x 150'), to place the sheets", False),
        ("arrows '{}', '{}': the world axes along the paper's right and up".format(
            *(f"world {a}" for a in page_axes(frame))), False),
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
    pdf.text(x0, _PARTS_Y, "Parts, in placement order, then ropes [the sheets they are on]", 2.8,
             bold=True)
    for i, lines in enumerate(_parts_list(parts, (w, h), sheets, drawing.ropes)):
        if i:
            pdf.new_page(w, h)
            pdf.text(x0, MARGIN_MM + 5.0, f"{title} - parts, continued", 2.8, bold=True)
        for x, y, text in lines:
            pdf.text(x, y, text, 2.2, bold=False)


def write_pdf(path: Path, title: str, drawing: Drawing, parts, frame: PlaneFrame,
              map_sheet: SheetInfo, sheets: tuple[SheetInfo, ...], grid: tuple[int, int],
              paper: str, orientation: str, overlap_mm: float,
              empty: set[str] = frozenset(), note: str = "", seams=None, clear=None,
              making=None) -> int:
    """Write the template's PDF; returns its number of pages. ``empty``: labels of the
    sheets with nothing to place (:func:`empty_sheets`), which say so; ``note``: a line
    beside the assembly map (how often the layout works when built by hand); ``seams``: the
    sheets' (:func:`seams_of`, computed here when None); ``clear``: the parts (a shapely
    geometry, drawing mm), which tick labels keep off; ``making``: the bill of materials and
    the assembly steps (:class:`~rgmcad.printing.making_pages.Making`), drawn after the parts
    list (:func:`~rgmcad.printing.making_pages.making_page_count` pages).

    ``parts`` are the drawing's :class:`rgmcad.printing.drawing.PartOutline` in placement
    order; ``sheets`` the tiled sheets, numbered after :func:`cover_page_count` pages.
    """
    pdf = _Pdf(path, title)
    _cover_pages(pdf, drawing, parts, map_sheet, sheets, grid, title, frame, paper,
                 orientation, overlap_mm, empty, note)
    if making is not None:  # the bill of materials and the assembly steps
        where = {p.name: part_sheets(p, sheets) for p in parts}
        draw_making_pages(pdf, making, map_sheet.size_mm, title, where)
    seams = seams_of(sheets) if seams is None else seams
    for info in sheets:
        tile_page(pdf, drawing, info, seams, grid, title, paper, frame,
                  empty=info.label in empty, clear=clear)
    with naming(path):
        pdf.save()
    return pdf.pages
