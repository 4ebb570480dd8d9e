"""Printable 1:1 assembly templates of a posed layout, tiled over sheets of paper.

A layout's parts are projected on one plane (the floor they stand on, the board they are
pinned to, or an axis plane) and drawn at true scale: each part's exact silhouette (the
union of its projected mesh triangles), its placement order and name, its height above the
plane, the tilt the outline cannot show, and its tolerances. The drawing is cut into sheets
with overlap strips, each sheet carrying its label, a 100 mm scale bar, "print at 100 %" and
four AprilTag 36h11 marks from which :func:`rgmcad.printing.check.verify_print` recognises the
sheet and measures the printer's scale. The first page holds an assembly map, test squares
(100 mm and 1 in), the parts list and a legend. The same drawing is written as one SVG at
1:1 in millimetres.

Coordinates
-----------
*World*: metres, Z up. *Drawing*: millimetres in the template plane, ``u`` to the right and
``v`` up as the builder sees the plane (from the side its normal points to), so the drawing
is never mirrored: ``u_axis x v_axis = normal``. *Sheet* (page) coordinates: millimetres from
the top-left corner of the printed page, ``x`` right, ``y`` down (like a raster image).

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
:func:`sheet_marks` gives them from the ids alone; ``verify_print`` tells the paper size
from the marks' spacing.
"""

from __future__ import annotations

import functools
import logging
import math
import string
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Polygon
from shapely.geometry import box as shapely_box
from shapely.ops import nearest_points

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

# --- paper, sheet layout and marks --------------------------------------------------------------

PAPERS_MM: dict[str, tuple[float, float]] = {
    "a4": (210.0, 297.0),
    "letter": (215.9, 279.4),
    "a3": (297.0, 420.0),
}
"""Paper sizes, portrait ``(width, height)`` in mm."""

ORIENTATIONS = ("portrait", "landscape")
PLANES = ("floor", "board", "xy", "xz", "yz")

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

_PALETTE = (
    (1.00, 0.80, 0.80),
    (0.80, 0.88, 1.00),
    (0.80, 0.95, 0.78),
    (1.00, 0.92, 0.68),
    (0.90, 0.80, 1.00),
    (0.76, 0.95, 0.95),
    (0.96, 0.84, 0.70),
    (0.90, 0.90, 0.78),
)
"""Light fill colours of the parts (RGB in 0..1), cycled in placement order."""

_NAME_MM = 2.6  # font size of a part's name, mm
_NOTE_MM = 2.0  # font size of notes, mm
_OUTLINE_MM = 0.25  # outline stroke width, mm
_TOUCH_M = 0.005  # a part whose lowest point is this close to a base plane rests on it


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


def _tag_quads(tag_id: int, corners: np.ndarray) -> list[np.ndarray]:
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


# --- inputs ---------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PlacedPart:
    """One posed part of a layout.

    Attributes
    ----------
    name : str
        e.g. ``"track"``, ``"run[3]"``.
    order : int
        Placement order, 1-based.
    vertices : (n, 3) float
        The part's exact CAD mesh in world coordinates, metres.
    faces : (m, 3) int
        Triangles of the mesh.
    pose : (4, 4) float
        World pose of the part's frame (metres).
    tolerances : tuple of str
        Ready-made notes, e.g. ``"x ± 3 mm"``.
    """

    name: str
    order: int
    vertices: np.ndarray
    faces: np.ndarray
    pose: np.ndarray
    tolerances: tuple[str, ...] = ()


@dataclass(frozen=True)
class BasePlane:
    """An infinite plane of the scenario (floor, board); never drawn.

    ``point`` (3,) metres and unit ``normal`` (3,), world coordinates.
    """

    name: str
    point: np.ndarray
    normal: np.ndarray


# --- the plane of the drawing ---------------------------------------------------------------------


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


_AXIS_FRAMES = {
    # u right, v up, viewer on the side of u x v
    "xy": ((1.0, 0, 0), (0, 1.0, 0)),  # seen from +Z
    "xz": ((1.0, 0, 0), (0, 0, 1.0)),  # seen from -Y (the paper's 'xz')
    "yz": ((0, 1.0, 0), (0, 0, 1.0)),  # seen from +X
}


def _axis_frame(name: str) -> PlaneFrame:
    u, v = (np.array(a, float) for a in _AXIS_FRAMES[name])
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
    if plane in _AXIS_FRAMES:
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


# --- parts on the drawing -------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PartOutline:
    """A part as drawn.

    Attributes
    ----------
    name : str
    order : int
    outline : shapely Polygon or MultiPolygon
        Silhouette in drawing mm.
    centroid_mm : (2,) float
        Area centroid of the silhouette, drawing mm.
    centroid_world : (3,) float
        That centroid as a world point on the template plane, metres.
    lowest_mm, origin_mm : float
        Height above the plane (signed distance along its normal) of the part's lowest point
        and of its frame origin, mm.
    tilt_deg : float
        Smallest angle between one of the part frame's axes and the plane's normal, degrees
        (0 when the part is square to the plane; the outline cannot show it otherwise).
    notes : tuple of str
        Lines printed beside the outline after the name (height, tilt, tolerances).
    fill_rgb : (float, float, float)
        Fill colour on the drawing, 0..1.
    label_box : (4,) float
        ``(u0, v0, u1, v1)`` of the label block, drawing mm.
    tolerances : tuple of str
        The part's tolerances, as given.
    """

    name: str
    order: int
    outline: Polygon | MultiPolygon
    centroid_mm: np.ndarray
    centroid_world: np.ndarray
    lowest_mm: float
    origin_mm: float
    tilt_deg: float
    notes: tuple[str, ...]
    fill_rgb: tuple[float, float, float]
    label_box: tuple[float, float, float, float]
    tolerances: tuple[str, ...] = ()


def silhouette(vertices: np.ndarray, faces: np.ndarray, frame: PlaneFrame):
    """Exact silhouette of a mesh projected on the frame's plane, drawing mm.

    The union of the projected triangles (edge-on ones dropped); for a closed mesh only the
    triangles facing the viewer are needed (they cover the projection). Holes and islands
    under 0.01 mm² (numerical slivers) are removed.

    Returns
    -------
    shapely Polygon or MultiPolygon
    """
    uv = frame.to_drawing(vertices)
    tri = uv[np.asarray(faces, int)]
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    front, back = cross > 1e-9, cross < -1e-9
    area_f, area_b = cross[front].sum(), -cross[back].sum()
    closed = area_f > 0 and abs(area_f - area_b) <= 1e-3 * area_f
    keep = front if closed else (front | back)
    if not keep.any():
        raise ValueError("the part's mesh projects to nothing on the template plane")
    geom = shapely.union_all(shapely.polygons(tri[keep]))
    polys = []
    for g in getattr(geom, "geoms", [geom]):
        if not isinstance(g, Polygon) or g.area < 0.01:
            continue
        holes = [r for r in g.interiors if Polygon(r).area >= 0.01]
        polys.append(Polygon(g.exterior, holes))
    return polys[0] if len(polys) == 1 else MultiPolygon(polys)


def _axis_name(direction: np.ndarray) -> str:
    for i, name in enumerate("XYZ"):
        if abs(direction[i]) > 0.999:
            return ("+" if direction[i] > 0 else "-") + name
    return ""


def _tilt(pose: np.ndarray, normal: np.ndarray) -> tuple[float, str]:
    r = np.asarray(pose, float)[:3, :3]
    cosines = np.clip(np.abs(r.T @ normal), 0.0, 1.0)
    i = int(np.argmax(cosines))
    return float(np.degrees(np.arccos(cosines[i]))), "xyz"[i]


def _height_note(frame: PlaneFrame, lo_mm: float, hi_mm: float, origin_mm: float) -> str:
    if frame.kind in _AXIS_FRAMES:
        axis = {"xy": "z", "xz": "y", "yz": "x"}[frame.kind]
        sign = 1.0 if frame.normal @ np.ones(3) > 0 else -1.0
        # world coordinate along the normal's axis (the axis frames' normals are +-axes)
        lo, hi = sorted((sign * lo_mm, sign * hi_mm))
        return f"{axis} {lo:.0f} to {hi:.0f} mm"
    where = {"floor": "above floor", "board": "from board"}.get(frame.kind, f"from {frame.base}")
    lead = {"floor": "bottom", "board": "back"}.get(frame.kind, "nearest")
    if abs(lo_mm) < 0.5:
        return f"{lead} on {frame.kind if frame.kind != 'plane' else frame.base}, origin " \
            f"{origin_mm:.0f} mm {where}"
    return f"{lead} {lo_mm:.0f} mm, origin {origin_mm:.0f} mm {where}"


def _part_notes(part: PlacedPart, frame: PlaneFrame):
    h = frame.height(part.vertices) * 1000.0
    lo, hi = float(h.min()), float(h.max())
    origin = float(frame.height(np.asarray(part.pose, float)[:3, 3])[0] * 1000.0)
    tilt, axis = _tilt(part.pose, frame.normal)
    notes = [_height_note(frame, lo, hi, origin)]
    if tilt > 0.5:
        notes.append(f"tilt {tilt:.1f}° out of plane (local {axis} axis vs normal)")
    return lo, origin, tilt, notes


# --- a device-independent drawing -----------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class _Path:
    rings: tuple[np.ndarray, ...]  # (k, 2) drawing mm each
    closed: bool = True
    fill: tuple[float, float, float] | None = None
    stroke: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
    width: float = 0.2  # mm
    dash: tuple[float, ...] = ()  # mm
    cls: str = ""  # SVG class / id hint
    ident: str = ""


@dataclass(frozen=True)
class _Text:
    x: float
    y: float  # baseline, drawing mm (v up)
    text: str
    size: float  # mm
    bold: bool = False
    anchor: str = "start"  # start | middle | end
    colour: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _font(bold: bool) -> str:
    return "Helvetica-Bold" if bold else "Helvetica"


def _pdf_safe(text: str) -> str:
    """Text in the standard fonts' encoding (WinAnsi): anything else becomes '?'."""
    return text.encode("cp1252", "replace").decode("cp1252")


def _text_width(text: str, size: float, bold: bool = False) -> float:
    from reportlab.pdfbase.pdfmetrics import stringWidth

    return stringWidth(_pdf_safe(text), _font(bold), size)


def _wrap(text: str, size: float, width: float, bold: bool = False) -> list[str]:
    """Split ``text`` into lines no wider than ``width`` mm at font size ``size`` mm."""
    lines: list[str] = []
    for word in text.split():
        if lines and _text_width(lines[-1] + " " + word, size, bold) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return lines or [""]


def _rings(geom) -> list[np.ndarray]:
    rings = []
    for g in getattr(geom, "geoms", [geom]):
        rings.append(np.asarray(g.exterior.coords)[:-1])
        rings.extend(np.asarray(r.coords)[:-1] for r in g.interiors)
    return rings


def _label_lines(part: PlacedPart, notes: list[str]) -> list[tuple[str, float, bool]]:
    lines = [(f"{part.order}. {part.name}", _NAME_MM, True)]
    lines += [(n, _NOTE_MM, False) for n in notes]
    if part.tolerances:
        for chunk in _wrap(", ".join(part.tolerances), _NOTE_MM, 60.0):
            lines.append((chunk, _NOTE_MM, False))
    return lines


def _block_size(lines) -> tuple[float, float]:
    width = max(_text_width(t, s, b) for t, s, b in lines) + 1.0
    height = sum(1.25 * s for _, s, _ in lines) + 1.0
    return width, height


def _place_labels(outlines, sizes) -> list[tuple[float, float, float, float]]:
    """Greedy label placement beside each outline, avoiding outlines and earlier labels.

    Candidates are tried around the outline's bounding box at growing distances; the first
    free one wins, else the one that overlaps least.
    """
    obstacles = [o.buffer(1.0) for o in outlines]
    bounds = [np.array(o.bounds) for o in obstacles]
    boxes: list[tuple[float, float, float, float]] = []

    def overlap(b):
        cost = 0.0
        bb = b.bounds
        for g, gb in zip(obstacles, bounds, strict=True):
            if gb[0] < bb[2] and bb[0] < gb[2] and gb[1] < bb[3] and bb[1] < gb[3]:
                cost += b.intersection(g).area
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
        for d in (2.0, 6.0, 12.0, 20.0, 35.0, 60.0):
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
        best, best_cost = cands[0], math.inf
        for i, (x0, y0) in enumerate(cands):
            cost = overlap(shapely_box(x0, y0, x0 + w, y0 + h)) + 1e-3 * i
            if cost < best_cost:
                best, best_cost = (x0, y0), cost
            if cost < 1e-3 * (i + 1):
                break
        if best_cost > 1.0:
            log.info("label %d overlaps other drawing by %.1f mm²", k, best_cost)
        x0, y0 = best
        boxes.append((x0, y0, x0 + w, y0 + h))
    return boxes


def _text_items(box, lines) -> list[_Text]:
    x0, _, _, y1 = box
    items, top = [], 0.5
    for text, size, bold in lines:
        top += 1.25 * size
        items.append(_Text(x0 + 0.5, y1 - top + 0.3 * size, text, size, bold))
    return items


def _plane_lines(frame: PlaneFrame, base_planes, extent) -> list[tuple[str, np.ndarray]]:
    """Where other base planes cut the template plane, clipped to the extent (drawing mm)."""
    u0, v0, u1, v1 = extent
    area = shapely_box(u0, v0, u1, v1)
    out = []
    for bp in base_planes:
        m = np.asarray(bp.normal, float)
        m = m / np.linalg.norm(m)
        a = np.array([m @ frame.u_axis, m @ frame.v_axis])  # plane Q in drawing coords:
        if np.linalg.norm(a) < 1e-6:  # a . (u, v) = c
            continue
        c = 1000.0 * float(m @ (np.asarray(bp.point, float) - frame.origin))
        p = a * c / (a @ a)
        d = np.array([-a[1], a[0]]) / np.linalg.norm(a)
        span = 2.0 * (abs(u0) + abs(u1) + abs(v0) + abs(v1) + np.linalg.norm(p))
        seg = LineString([p - span * d, p + span * d]).intersection(area)
        if not seg.is_empty and seg.length > 1.0:
            out.append((bp.name, np.asarray(seg.coords)))
    return out


@dataclass(frozen=True, eq=False)
class _Drawing:
    items: tuple  # _Path | _Text, in drawing order
    extent: tuple[float, float, float, float]  # u0, v0, u1, v1 mm
    minimap: tuple  # _Path items for the assembly map (no text)


def _build_drawing(parts, base_planes, frame: PlaneFrame):
    parts = sorted(parts, key=lambda p: (p.order, p.name))
    outlines, infos, sizes, line_sets = [], [], [], []
    for p in parts:
        try:
            geom = silhouette(p.vertices, p.faces, frame)
        except ValueError as exc:
            raise ValueError(f"part {p.name!r}: {exc}") from None
        lo, origin, tilt, notes = _part_notes(p, frame)
        lines = _label_lines(p, notes)
        outlines.append(geom)
        infos.append((lo, origin, tilt, notes))
        line_sets.append(lines)
        sizes.append(_block_size(lines))
    boxes = _place_labels(outlines, sizes)

    fills, strokes, texts, leaders = [], [], [], []
    results = []
    for k, (p, geom) in enumerate(zip(parts, outlines, strict=True)):
        rgb = _PALETTE[k % len(_PALETTE)]
        rings = tuple(_rings(geom))
        ident = f"part-{k + 1}"
        fills.append(_Path(rings, fill=rgb, stroke=None, cls="part-fill", ident=ident))
        strokes.append(_Path(rings, width=_OUTLINE_MM, cls="part-outline", ident=ident + "-o"))
        box = boxes[k]
        texts += _text_items(box, line_sets[k])
        pb, po = nearest_points(shapely_box(*box), geom)
        if pb.distance(po) > 0.8:
            leaders.append(
                _Path((np.array([[pb.x, pb.y], [po.x, po.y]]),), closed=False,
                      stroke=(0.35, 0.35, 0.35), width=0.15, cls="leader")
            )
        c = np.array(geom.centroid.coords[0])
        lo, origin, tilt, notes = infos[k]
        results.append(
            PartOutline(p.name, p.order, geom, c, frame.to_world(c)[0], lo, origin, tilt,
                        tuple(notes), rgb, box, tuple(p.tolerances))
        )

    bounds = np.array([g.bounds for g in outlines] + list(boxes))
    pad = 5.0
    extent = (bounds[:, 0].min() - pad, bounds[:, 1].min() - pad,
              bounds[:, 2].max() + pad, bounds[:, 3].max() + pad)

    refs = []
    for name, seg in _plane_lines(frame, base_planes, extent):
        refs.append(_Path((seg,), closed=False, stroke=(0.3, 0.3, 0.3), width=0.2,
                          dash=(6.0, 1.5, 1.0, 1.5), cls="base-plane"))
        a, b = seg[0], seg[-1]
        ang = math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))
        if -90 <= ang <= 90:
            start = a
        else:
            start = b
        texts.append(_Text(float(start[0]) + 2.0, float(start[1]) + 0.8,
                           f"{name} (base plane)", _NOTE_MM, colour=(0.3, 0.3, 0.3)))
    u0, v0, u1, v1 = extent
    ou, ov = frame.to_drawing(np.zeros(3))[0]  # the world origin, projected
    if u0 + 5 < ou < u1 - 15 and v0 + 5 < ov < v1 - 15:
        o = np.array([ou, ov])
        for d, name, at in ((np.array([1.0, 0.0]), _axis_name(frame.u_axis), (11.0, -0.8)),
                            (np.array([0.0, 1.0]), _axis_name(frame.v_axis), (1.0, 10.5))):
            tip = o + 10.0 * d
            side = np.array([-d[1], d[0]])
            refs.append(_Path((np.array([o, tip]),), closed=False, width=0.2, cls="origin"))
            refs.append(_Path((np.array([tip, tip - 1.5 * d + 0.6 * side,
                                         tip - 1.5 * d - 0.6 * side]),), fill=(0, 0, 0),
                              stroke=None, cls="origin"))
            if name:
                texts.append(_Text(ou + at[0], ov + at[1], name, _NOTE_MM))
        texts.append(_Text(ou + 0.8, ov - 3.0, "world origin", _NOTE_MM))

    items = tuple(fills + strokes + refs + leaders + texts)
    minimap = tuple(fills + strokes)
    return _Drawing(items, extent, minimap), tuple(results)


# --- the sheet grid -------------------------------------------------------------------------------


def window_size_mm(paper: str, orientation: str) -> tuple[float, float]:
    """Size ``(width, height)`` of the drawing window of a sheet, mm.

    The page less ``MARGIN_MM`` all round and a ``BAND_MM`` band at top and bottom.
    """
    w, h = page_size_mm(paper, orientation)
    return w - 2 * MARGIN_MM, h - 2 * MARGIN_MM - 2 * BAND_MM


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


def _choose_paper(width, height, paper, orientation, overlap):
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

    def page_to_drawing(self) -> np.ndarray:
        """(3, 3) affine map from sheet mm (y down) to drawing mm (v up) in the window."""
        x0, y0, _, _ = self.window_mm
        u0, _, _, v1 = self.region_mm
        return np.array([[1.0, 0.0, u0 - x0], [0.0, -1.0, v1 + y0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class TemplateResult:
    """What :func:`make_template` wrote.

    Attributes
    ----------
    pdf, svg : Path
        The files.
    plane : str
        Kind of plane used: ``"floor"``, ``"board"``, ``"xy"``, ``"xz"``, ``"yz"``, ``"plane"``.
    frame : PlaneFrame
        The plane's frame (world <-> drawing mm).
    paper, orientation : str
    grid : (int, int)
        ``(cols, rows)`` of tiled sheets.
    sheet_labels : tuple of str
        Labels of the tiled sheets in page order (row by row).
    sheets : tuple of SheetInfo
        The tiled sheets, in page order.
    map_sheet : SheetInfo
        The first page.
    tag_centres : dict
        ``{label: {tag_id: (x, y)}}`` planned mark centres per page (``"map"`` included),
        sheet mm.
    parts : tuple of PartOutline
        In placement order.
    extent_mm : (float, float, float, float)
        ``(u0, v0, u1, v1)`` of the whole drawing, drawing mm; the SVG's viewBox is
        ``0 0 (u1 - u0) (v1 - v0)`` with SVG ``x = u - u0`` and ``y = v1 - v``.
    overlap_mm : float
        Width of the strips neighbouring sheets share, mm.
    n_pages : int
        Pages in the PDF: the first page, parts-list continuation pages, the sheets.
    """

    pdf: Path
    svg: Path
    plane: str
    frame: PlaneFrame
    paper: str
    orientation: str
    grid: tuple[int, int]
    sheet_labels: tuple[str, ...]
    sheets: tuple[SheetInfo, ...]
    map_sheet: SheetInfo
    tag_centres: dict
    parts: tuple[PartOutline, ...]
    extent_mm: tuple[float, float, float, float]
    overlap_mm: float
    n_pages: int = 0


def _sheet_info(label, col, row, page, paper, orientation, slot, window=None, region=None):
    marks = sheet_marks(paper, orientation, slot)
    centres = {i: tuple(float(v) for v in c.mean(0)) for i, c in marks.items()}
    extra = {}
    if window is not None:
        extra = {"window_mm": window, "region_mm": region}
    return SheetInfo(label, col, row, page, orientation, page_size_mm(paper, orientation),
                     tuple(marks), marks, centres, **extra)


# --- PDF ----------------------------------------------------------------------------------------


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
        c.setFont(_font(bold), size)
        t = _pdf_safe(text)
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
        for q in _tag_quads(tag_id, corners_down):
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
            if isinstance(it, _Text):
                if skip_text:
                    continue
                c.setFillColorRGB(*it.colour)
                c.setFont(_font(it.bold), it.size)
                t = _pdf_safe(it.text)
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
    lx = x0 + _text_width(label, 8.0, True) + 4.0
    y = MARGIN_MM + 3.5
    for i, line in enumerate(lines[:5]):
        size = 2.6 if i == 0 else 2.2
        while _text_width(line, size, i == 0) > x1 - lx and len(line) > 4:
            line = line[:-2]
        pdf.text(lx, y, line, size, bold=(i == 0))
        y += 1.35 * size + 0.2


def _bottom_band(pdf: _Pdf, text: str):
    x0 = MARGIN_MM + TAG_SIDE_MM + 5.0
    y_bar = pdf.h - MARGIN_MM - BAND_MM + 8.0
    _scale_bar(pdf, x0, y_bar)
    pdf.text(x0, y_bar + 6.5, "scale bar: 100 mm", 2.0)
    room = pdf.w - MARGIN_MM - TAG_SIDE_MM - 3.0 - (x0 + 104.0)
    for i, chunk in enumerate(_wrap(text, 2.0, room)[:4]):
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
    y_bottom = h - MARGIN_MM - BAND_MM

    # assembly map
    pdf.text(x0, y_top + 3.0, "Assembly map", 3.0, bold=True)
    box_y, box_h = y_top + 5.0, 68.0
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
    sq_y = box_y + box_h + 6.0
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
        for chunk in _wrap(text, 2.2, w - MARGIN_MM - lx, bold):
            if ly > sq_y + 100.0:
                break
            pdf.text(lx, ly, chunk, 2.2, bold=bold)
            ly += 2.9

    # parts list, continued on further pages when long
    rows_text = []
    for p in parts:
        notes = "; ".join([*p.notes, *p.tolerances])
        first = True
        for chunk in _wrap(f"{p.order}. {p.name}: {notes}", 2.2, ww - 6.0):
            rows_text.append((chunk if first else "    " + chunk, first))
            first = False
    y = sq_y + 100.0 + 7.0
    pdf.text(x0, y, "Parts, in placement order", 2.8, bold=True)
    y += 4.0
    for text, _first in rows_text:
        if y > y_bottom - 2.0:
            pdf.new_page(w, h)
            pdf.text(x0, MARGIN_MM + 5.0, f"{title} - parts, continued", 2.8, bold=True)
            y = MARGIN_MM + 10.0
            y_bottom = h - MARGIN_MM
        pdf.text(x0, y, text, 2.2, bold=False)
        y += 3.0


# --- SVG ------------------------------------------------------------------------------------------


def _hex(rgb) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


def _write_svg(path: Path, drawing: _Drawing, title: str):
    u0, v0, u1, v1 = drawing.extent
    w, h = u1 - u0, v1 - v0

    def xy(pts):
        return " ".join(f"{x - u0:.4f},{v1 - y:.4f}" for x, y in pts)

    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.4f}mm" height="{h:.4f}mm" '
        f'viewBox="0 0 {w:.4f} {h:.4f}">',
        f"<title>{escape(title or 'rgmcad assembly template')}</title>",
        f"<desc>1:1, user units are millimetres; drawing u = x + {u0:.4f}, "
        f"v = {v1:.4f} - y</desc>",
    ]
    for it in drawing.items:
        if isinstance(it, _Text):
            anchor = f' text-anchor="{it.anchor}"' if it.anchor != "start" else ""
            weight = ' font-weight="bold"' if it.bold else ""
            out.append(
                f'<text x="{it.x - u0:.3f}" y="{v1 - it.y:.3f}" font-family="Helvetica, '
                f'Arial, sans-serif" font-size="{it.size:.2f}"{weight}{anchor} '
                f'fill="{_hex(it.colour)}">{escape(it.text)}</text>'
            )
            continue
        d = " ".join(("M " + xy(r) + (" Z" if it.closed else "")) for r in it.rings)
        attrs = [f'd="{d}"']
        if it.ident:
            attrs.append(f"id={quoteattr(it.ident)}")
        if it.cls:
            attrs.append(f"class={quoteattr(it.cls)}")
        attrs.append(f'fill="{_hex(it.fill)}" fill-rule="evenodd"' if it.fill else 'fill="none"')
        if it.stroke is not None:
            attrs.append(f'stroke="{_hex(it.stroke)}" stroke-width="{it.width:.3f}"')
            if it.dash:
                attrs.append(f'stroke-dasharray="{" ".join(f"{v:g}" for v in it.dash)}"')
        out.append(f"<path {' '.join(attrs)}/>")
    out.append("</svg>")
    path.write_text("\n".join(out) + "\n", encoding="utf-8")


# --- entry point ----------------------------------------------------------------------------------


def make_template(parts, base_planes, out_dir, *, plane: str | None = None,
                  paper: str | None = None, orientation: str | None = None,
                  overlap_mm: float = 12.0, title: str = "") -> TemplateResult:
    """Write a printable 1:1 tiled assembly template of a posed layout.

    Parameters
    ----------
    parts : sequence of PlacedPart
        Posed parts (world metres).
    base_planes : sequence of BasePlane
        The scenario's infinite planes; never drawn, but the template plane may be one.
    out_dir : str or Path
        Folder for ``template.pdf`` and ``template.svg`` (created if missing).
    plane : str, optional
        ``"floor"``, ``"board"``, ``"xy"``, ``"xz"``, ``"yz"`` or a base plane's name; see
        :func:`resolve_plane` (None chooses).
    paper : str, optional
        ``"a4"``, ``"letter"`` or ``"a3"``; None picks the one that needs the fewest sheets
        (ties go to a4, then letter).
    orientation : str, optional
        ``"portrait"`` or ``"landscape"``; None picks the one with fewer sheets (ties:
        portrait).
    overlap_mm : float
        Width of the strips neighbouring sheets share, mm.
    title : str
        Printed on every page.

    Returns
    -------
    TemplateResult
    """
    parts = sorted(parts, key=lambda p: (p.order, p.name))
    if not parts:
        raise ValueError("no parts to draw")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    title = title or "rgmcad layout"
    frame = resolve_plane(parts, base_planes, plane)
    drawing, outlines = _build_drawing(parts, base_planes, frame)
    u0, v0, u1, v1 = drawing.extent
    width, height = u1 - u0, v1 - v0
    paper, orientation, cols, rows = _choose_paper(width, height, paper, orientation,
                                                   overlap_mm)
    ww, wh = window_size_mm(paper, orientation)
    sx, sy = ww - overlap_mm, wh - overlap_mm
    cov_w, cov_h = cols * sx + overlap_mm, rows * sy + overlap_mm
    left = u0 - (cov_w - width) / 2
    top = v1 + (cov_h - height) / 2
    log.info("template: plane %s, %s %s, %d x %d sheets, drawing %.0f x %.0f mm",
             frame.kind, paper, orientation, cols, rows, width, height)

    map_info = _sheet_info("map", -1, -1, 1, paper, "portrait", MAP_SLOT)
    # pages: map (and parts-list continuation pages), then sheets row by row
    pdf_path, svg_path = out_dir / "template.pdf", out_dir / "template.svg"
    pdf = _Pdf(pdf_path, title)
    pw, ph = page_size_mm(paper, orientation)
    window = (MARGIN_MM, MARGIN_MM + BAND_MM, pw - MARGIN_MM, ph - MARGIN_MM - BAND_MM)
    provisional = []
    for r in range(rows):
        for c in range(cols):
            ru0, rv1 = left + c * sx, top - r * sy
            provisional.append((sheet_label(c, r), c, r, sheet_slot(c, r),
                                (ru0, rv1 - wh, ru0 + ww, rv1)))
    tmp_sheets = tuple(
        _sheet_info(lab, c, r, 0, paper, orientation, slot, window, region)
        for lab, c, r, slot, region in provisional
    )
    _cover_pages(pdf, drawing, outlines, map_info, tmp_sheets, (cols, rows), title, frame,
                 paper, orientation, overlap_mm)
    first = pdf.pages + 1
    sheets = tuple(
        _sheet_info(lab, c, r, first + i, paper, orientation, slot, window, region)
        for i, (lab, c, r, slot, region) in enumerate(provisional)
    )
    _tile_pages(pdf, drawing, sheets, (cols, rows), title, overlap_mm, paper, frame)
    n_pages = pdf.pages
    pdf.save()
    _write_svg(svg_path, drawing, title)

    centres = {"map": dict(map_info.tag_centres_mm)}
    centres.update({s.label: dict(s.tag_centres_mm) for s in sheets})
    return TemplateResult(
        pdf=pdf_path, svg=svg_path, plane=frame.kind, frame=frame, paper=paper,
        orientation=orientation, grid=(cols, rows), sheet_labels=tuple(s.label for s in sheets),
        sheets=sheets, map_sheet=map_info, tag_centres=centres, parts=outlines,
        extent_mm=drawing.extent, overlap_mm=float(overlap_mm), n_pages=n_pages,
    )
