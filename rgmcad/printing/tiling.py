"""Tiling a drawing over sheets of paper: how many sheets, of which paper, and what each shows.

Neighbouring sheets share a strip of ``overlap_mm`` (one seam line through its middle, see
:mod:`rgmcad.printing.seams`), so
``n`` sheets cover ``n * (window - overlap) + overlap`` along a side; the grid is centred on
the drawing. Sheets go in page order, row by row from the top-left ``"A1"``.
"""

from __future__ import annotations

import math

from rgmcad.printing.seams import keep_area
from rgmcad.printing.sheets import (
    BAND_MM,
    MARGIN_MM,
    MAX_COLS,
    MAX_ROWS,
    ORIENTATIONS,
    PAPERS_MM,
    SheetInfo,
    page_size_mm,
    sheet_info,
    sheet_label,
    sheet_slot,
    window_size_mm,
)


def grid_size(width_mm: float, height_mm: float, paper: str, orientation: str,
              overlap_mm: float) -> tuple[int, int]:
    """Sheets ``(cols, rows)`` that cover a drawing of ``width_mm x height_mm``.

    Neighbouring windows share ``overlap_mm``, so ``n`` sheets cover
    ``n * (window - overlap) + overlap``.
    """
    ww, wh = window_size_mm(paper, orientation)
    if overlap_mm < 0 or overlap_mm >= min(ww, wh) / 2:
        raise ValueError(f"overlap_mm must be in [0, {min(ww, wh) / 2:.0f}), got {overlap_mm}")
    cols = max(1, math.ceil((width_mm - overlap_mm) / (ww - overlap_mm) - 1e-9))
    rows = max(1, math.ceil((height_mm - overlap_mm) / (wh - overlap_mm) - 1e-9))
    return cols, rows


def choose_paper(width: float, height: float, paper: str | None, orientation: str | None,
                 overlap: float) -> tuple[str, str, int, int]:
    """``(paper, orientation, cols, rows)`` needing the fewest sheets for a drawing, mm.

    ``paper`` or ``orientation`` None tries them all; ties go to the earlier paper of
    ``PAPERS_MM`` (a4, letter, a3), then portrait. Raises ``ValueError`` for an unknown
    name or a drawing that needs more than ``MAX_COLS x MAX_ROWS`` sheets.
    """
    papers = [paper] if paper else list(PAPERS_MM)
    orients = [orientation] if orientation else list(ORIENTATIONS)
    for p in papers:
        page_size_mm(p, orients[0])  # validates names
    for o in orients:
        page_size_mm(papers[0], o)
    best = None
    for pi, p in enumerate(papers):
        for oi, o in enumerate(orients):
            cols, rows = grid_size(width, height, p, o, overlap)
            if cols > MAX_COLS or rows > MAX_ROWS:
                continue
            key = (cols * rows, pi, oi)
            if best is None or key < best[0]:
                best = (key, p, o, cols, rows)
    if best is None:
        raise ValueError(
            f"the drawing ({width:.0f} x {height:.0f} mm) needs more than {MAX_COLS} x "
            f"{MAX_ROWS} sheets of {'/'.join(papers)}; use larger paper or split the layout"
        )
    return best[1:]


def tile_sheets(extent_mm, paper: str, orientation: str, grid: tuple[int, int],
                overlap_mm: float, first_page: int) -> tuple[SheetInfo, ...]:
    """The tiled sheets of a drawing in page order, numbered from ``first_page``.

    Parameters
    ----------
    extent_mm : (float, float, float, float)
        ``(u0, v0, u1, v1)`` of the drawing, drawing mm.
    paper, orientation : str
    grid : (int, int)
        ``(cols, rows)``, e.g. from :func:`choose_paper`.
    overlap_mm : float
        Width of the strips neighbouring sheets share, mm.
    first_page : int
        1-based PDF page of sheet ``"A1"`` (the pages before it: the first page and the
        parts list's continuation pages).
    """
    cols, rows = grid
    u0, v0, u1, v1 = extent_mm
    width, height = u1 - u0, v1 - v0
    ww, wh = window_size_mm(paper, orientation)
    sx, sy = ww - overlap_mm, wh - overlap_mm
    cov_w, cov_h = cols * sx + overlap_mm, rows * sy + overlap_mm
    left = u0 - (cov_w - width) / 2
    top = v1 + (cov_h - height) / 2
    pw, ph = page_size_mm(paper, orientation)
    window = (MARGIN_MM, MARGIN_MM + BAND_MM, pw - MARGIN_MM, ph - MARGIN_MM - BAND_MM)
    sheets = []
    for r in range(rows):
        for c in range(cols):
            ru0, rv1 = left + c * sx, top - r * sy
            region = (ru0, rv1 - wh, ru0 + ww, rv1)
            keep = keep_area(region, c, r, grid, overlap_mm)
            sheets.append(sheet_info(sheet_label(c, r), c, r, first_page + len(sheets), paper,
                                     orientation, sheet_slot(c, r), window, region, keep))
    return tuple(sheets)
