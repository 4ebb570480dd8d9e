"""Paper, sheets and the AprilTag marks on them: the layout shared by the template writer
and the print check.

Sheet (page) coordinates are millimetres from the top-left corner of the printed page, ``x``
right, ``y`` down (like a raster image). A page keeps ``MARGIN_MM`` blank all round, a band
of ``BAND_MM`` at top and bottom for marks and text, and the drawing window between.

Marks (tags) and their ids
--------------------------
Every tagged page (the first page, and every tiled sheet) carries four AprilTag 36h11 marks
at the corners of the printable area: black square ``TAG_BLACK_MM`` = 16 mm (8 cells of
2 mm: 6 data cells and the black border), in a white quiet zone of one cell, so each mark
takes ``TAG_SIDE_MM`` = 20 mm, its outer edge ``MARGIN_MM`` = 10 mm from the paper's edges.

``tag id = 4 * slot + corner``. ``slot`` 0 is the first page (the assembly map);
the tiled sheet of column ``col`` and row ``row`` (0-based; label ``"A1"`` is col 0,
row 0, top left) has ``slot = 1 + col + 12 * row``, so a template has at most 12 x 12 sheets
and ids 0..579 (the dictionary has 587). ``corner`` names the paper's corner *in the
portrait frame* (the sheet held with a short edge on top): 0 top-left, 1 top-right,
2 bottom-right, 3 bottom-left; a mark is drawn upright in that frame. A landscape sheet is
the portrait sheet turned a quarter turn clockwise (the portrait top-left corner becomes the
landscape top-right). Mark positions therefore depend on the paper size only, and
:func:`sheet_marks` gives them from the ids alone; :func:`rgmcad.printing.check.verify_print`
tells the paper size from the marks' spacing.
"""

from __future__ import annotations

import functools
import string
from dataclasses import dataclass

import numpy as np

PAPERS_MM: dict[str, tuple[float, float]] = {
    "a4": (210.0, 297.0),
    "letter": (215.9, 279.4),
    "a3": (297.0, 420.0),
}
"""Paper sizes, portrait ``(width, height)`` in mm."""

ORIENTATIONS = ("portrait", "landscape")

MARGIN_MM = 10.0
"""Blank margin around every page (printers leave 3-5 mm unprinted)."""
TAG_CELL_MM = 2.0
"""Side of one cell of a mark."""
TAG_CELLS = 8
"""Cells across a mark's black square: 6 data cells and a one-cell black border."""
TAG_BLACK_MM = TAG_CELLS * TAG_CELL_MM
"""Side of a mark's black square (16 mm): what the detector's corners outline."""
TAG_SIDE_MM = (TAG_CELLS + 2) * TAG_CELL_MM
"""Side of a mark with its white quiet zone (20 mm)."""
BAND_MM = TAG_SIDE_MM + 2.0
"""Height of the top and bottom bands of a page (marks and text); the drawing lies between."""
MAX_COLS = 12
MAX_ROWS = 12
MAP_SLOT = 0
"""Slot of the first page (assembly map)."""
N_TAG_IDS = 587
"""Number of ids of the AprilTag 36h11 dictionary."""

def page_size_mm(paper: str, orientation: str = "portrait") -> tuple[float, float]:
    """Page ``(width, height)`` in mm of a paper size in an orientation."""
    if paper not in PAPERS_MM:
        raise ValueError(f"unknown paper {paper!r}; choose one of {', '.join(PAPERS_MM)}")
    if orientation not in ORIENTATIONS:
        raise ValueError(
            f"unknown orientation {orientation!r}; choose one of {', '.join(ORIENTATIONS)}"
        )
    w, h = PAPERS_MM[paper]
    return (w, h) if orientation == "portrait" else (h, w)


def sheet_label(col: int, row: int) -> str:
    """Label of the sheet in column ``col`` and row ``row`` (0-based): ``"A1"``, ``"B2"``..."""
    return f"{string.ascii_uppercase[col]}{row + 1}"


def sheet_slot(col: int, row: int) -> int:
    """Tag slot of a tiled sheet (slot 0 is the first page)."""
    if not (0 <= col < MAX_COLS and 0 <= row < MAX_ROWS):
        raise ValueError(f"sheet ({col}, {row}) outside the {MAX_COLS} x {MAX_ROWS} grid")
    return 1 + col + MAX_COLS * row


def slot_label(slot: int) -> str:
    """Label of the page that carries tag slot ``slot``: ``"map"`` or a sheet label."""
    if slot == MAP_SLOT:
        return "map"
    col, row = (slot - 1) % MAX_COLS, (slot - 1) // MAX_COLS
    if not 0 <= row < MAX_ROWS:
        raise ValueError(f"tag slot {slot} is not used by rgmcad templates")
    return sheet_label(col, row)


def decode_tag_id(tag_id: int) -> tuple[int, int]:
    """``(slot, corner)`` of a tag id (see the module docstring)."""
    tag_id = int(tag_id)
    slot, corner = divmod(tag_id, 4)
    if tag_id < 0 or slot > MAX_COLS * MAX_ROWS:
        raise ValueError(f"tag id {tag_id} is not used by rgmcad templates")
    return slot, corner


def portrait_to_page(points: np.ndarray, paper: str, orientation: str) -> np.ndarray:
    """Map (n, 2) points from the portrait frame to the page frame of ``orientation`` (mm).

    Both frames have their origin at the page's top-left corner, ``x`` right, ``y`` down.
    A landscape page is the portrait page turned a quarter turn clockwise.
    """
    p = np.asarray(points, float).reshape(-1, 2)
    if orientation == "portrait":
        return p.copy()
    _, h = PAPERS_MM[paper]
    return np.column_stack([h - p[:, 1], p[:, 0]])


def mark_corners_portrait(paper: str) -> dict[int, np.ndarray]:
    """Corners of the four marks' black squares in the portrait frame, mm.

    Returns ``{corner: (4, 2) array}``, the mark's own top-left, top-right, bottom-right and
    bottom-left corners (the order of OpenCV's detector), for corner 0 (top-left of the
    page), 1 (top-right), 2 (bottom-right) and 3 (bottom-left).
    """
    w, h = PAPERS_MM[paper]
    half = TAG_SIDE_MM / 2
    centres = {
        0: (MARGIN_MM + half, MARGIN_MM + half),
        1: (w - MARGIN_MM - half, MARGIN_MM + half),
        2: (w - MARGIN_MM - half, h - MARGIN_MM - half),
        3: (MARGIN_MM + half, h - MARGIN_MM - half),
    }
    b = TAG_BLACK_MM / 2
    square = np.array([[-b, -b], [b, -b], [b, b], [-b, b]])
    return {c: square + np.array(xy) for c, xy in centres.items()}


def sheet_marks(paper: str, orientation: str, slot: int) -> dict[int, np.ndarray]:
    """Tag ids and black-square corners of a page, mm in that page's frame.

    This is the one layout rule shared by the template writer and the print checker.

    Parameters
    ----------
    paper : str
        ``"a4"``, ``"letter"`` or ``"a3"``.
    orientation : str
        ``"portrait"`` or ``"landscape"``: the frame of the returned coordinates.
    slot : int
        0 for the first page, :func:`sheet_slot` for a tiled sheet.

    Returns
    -------
    dict
        ``{tag_id: (4, 2) float}``, corners in the detector's order (mark's top-left,
        top-right, bottom-right, bottom-left), mm from the page's top-left corner, y down.
    """
    return {
        4 * slot + c: portrait_to_page(pts, paper, orientation)
        for c, pts in mark_corners_portrait(paper).items()
    }


@functools.cache
def _tag_cells(tag_id: int) -> np.ndarray:
    """(8, 8) bool, True where the mark's cell is black (row 0 on top)."""
    import cv2

    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    image = cv2.aruco.generateImageMarker(dictionary, int(tag_id), TAG_CELLS)
    return image < 128


def tag_quads(tag_id: int, corners: np.ndarray) -> list[np.ndarray]:
    """Black runs of a mark as (4, 2) quads, given its square's corners (TL, TR, BR, BL)."""
    cells = _tag_cells(tag_id)
    tl, tr, _, bl = np.asarray(corners, float)
    ex, ey = (tr - tl) / TAG_CELLS, (bl - tl) / TAG_CELLS

    def at(i, j):
        return tl + j * ex + i * ey

    quads = []
    for i in range(TAG_CELLS):
        j = 0
        while j < TAG_CELLS:
            if not cells[i, j]:
                j += 1
                continue
            j0 = j
            while j < TAG_CELLS and cells[i, j]:
                j += 1
            quads.append(np.array([at(i, j0), at(i, j), at(i + 1, j), at(i + 1, j0)]))
    return quads


def window_size_mm(paper: str, orientation: str) -> tuple[float, float]:
    """Size ``(width, height)`` of the drawing window of a sheet, mm.

    The page less ``MARGIN_MM`` all round and a ``BAND_MM`` band at top and bottom.
    """
    w, h = page_size_mm(paper, orientation)
    return w - 2 * MARGIN_MM, h - 2 * MARGIN_MM - 2 * BAND_MM


@dataclass(frozen=True, eq=False)
class SheetInfo:
    """One tagged page of the template.

    Attributes
    ----------
    label : str
        ``"A1"``...; ``"map"`` for the first page.
    col, row : int
        0-based position in the grid (-1 for the first page).
    page : int
        1-based page number in the PDF.
    orientation : str
        ``"portrait"`` or ``"landscape"``.
    size_mm : (float, float)
        Page width and height, mm.
    tag_ids : tuple of int
        Ids of the four marks.
    tag_corners_mm : dict
        ``{tag_id: (4, 2) float}`` black-square corners, sheet mm (top-left origin, y down).
    tag_centres_mm : dict
        ``{tag_id: (x, y)}`` mark centres, sheet mm.
    window_mm : (float, float, float, float)
        ``(x0, y0, x1, y1)`` of the drawing window, sheet mm (tiled sheets only).
    region_mm : (float, float, float, float)
        ``(u0, v0, u1, v1)`` of the drawing shown in the window, drawing mm.
    keep_mm : (float, float, float, float)
        ``(u0, v0, u1, v1)`` of the drawing this sheet shows once cut along its seam lines
        and laid on its neighbours (see :mod:`rgmcad.printing.seams`), drawing mm.
    """

    label: str
    col: int
    row: int
    page: int
    orientation: str
    size_mm: tuple[float, float]
    tag_ids: tuple[int, ...]
    tag_corners_mm: dict
    tag_centres_mm: dict
    window_mm: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    region_mm: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    keep_mm: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)

    def page_to_drawing(self) -> np.ndarray:
        """(3, 3) affine map from sheet mm (y down) to drawing mm (v up) in the window."""
        x0, y0, _, _ = self.window_mm
        u0, _, _, v1 = self.region_mm
        return np.array([[1.0, 0.0, u0 - x0], [0.0, -1.0, v1 + y0], [0.0, 0.0, 1.0]])

    def to_drawing(self, x: float, y: float) -> tuple[float, float]:
        """Drawing ``(u, v)`` mm of sheet point ``(x, y)`` mm (y down)."""
        x0, y0, _, _ = self.window_mm
        u0, _, _, v1 = self.region_mm
        return u0 + (x - x0), v1 - (y - y0)

    def to_page(self, u: float, v: float) -> tuple[float, float]:
        """Sheet mm (y down) of drawing point ``(u, v)`` mm."""
        x0, y0, _, _ = self.window_mm
        u0, _, _, v1 = self.region_mm
        return x0 + (u - u0), y0 + (v1 - v)


def sheet_info(label, col, row, page, paper, orientation, slot, window=None,
               region=None, keep=None) -> SheetInfo:
    """The :class:`SheetInfo` of a page: its marks from the paper and the slot alone.

    ``window``, ``region`` and ``keep`` (tiled sheets only) are ``window_mm``,
    ``region_mm`` and ``keep_mm``.
    """
    marks = sheet_marks(paper, orientation, slot)
    centres = {i: tuple(float(v) for v in c.mean(0)) for i, c in marks.items()}
    extra = {}
    if window is not None:
        extra = {"window_mm": window, "region_mm": region, "keep_mm": keep or region}
    return SheetInfo(label, col, row, page, orientation, page_size_mm(paper, orientation),
                     tuple(marks), marks, centres, **extra)
