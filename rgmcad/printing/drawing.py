"""The drawing of a template: parts' silhouettes, labels and reference lines, in drawing mm.

:func:`build_drawing` turns posed parts into a device-independent list of items
(:class:`PathItem`, :class:`TextItem`) that the PDF and SVG writers render alike: each part's
exact silhouette (the union of its projected mesh triangles), its placement order and name,
its height above the plane, the tilt the outline cannot show, and its tolerances; where other
base planes cut the template plane; the world origin's axes when it lies on the drawing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import shapely
from shapely.geometry import LineString, MultiPolygon, Point, Polygon
from shapely.geometry import box as shapely_box
from shapely.ops import nearest_points

from rgmcad.printing.inputs import PlacedPart
from rgmcad.printing.labels import NOTE_MM, block_size, label_lines, place_labels
from rgmcad.printing.plane import AXIS_FRAMES, PlaneFrame
from rgmcad.printing.ropes import (
    ROPE_MM,
    ROPE_RGB,
    RopeOutline,
    point_ring,
    rope_lines,
    rope_path,
)

PALETTE = (
    (1.00, 0.80, 0.80),
    (0.80, 0.88, 1.00),
    (0.80, 0.95, 0.78),
    (1.00, 0.92, 0.68),
    (0.90, 0.80, 1.00),
    (0.76, 0.95, 0.95),
    (0.96, 0.84, 0.70),
    (0.90, 0.90, 0.78),
)
"""Light fill colours of the parts (RGB in 0..1), cycled in placement order (see
:func:`fill_colours`)."""

OUTLINE_MM = 0.25
"""Stroke width of a part's outline, mm."""
POINT_MM_PAD = 1.5
"""How far (mm) labels keep from a rope's path."""


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


def _tilt(pose: np.ndarray, normal: np.ndarray) -> tuple[float, str, np.ndarray]:
    """Tilt (degrees) of the part axis nearest the plane's normal, its name, and the world
    direction in the plane its end away from the plane leans towards."""
    r = np.asarray(pose, float)[:3, :3]
    dots = r.T @ normal
    i = int(np.argmax(np.abs(dots)))
    a = r[:, i] * np.sign(dots[i] or 1.0)
    lean = a - (a @ normal) * normal
    return float(np.degrees(np.arccos(min(1.0, abs(dots[i]))))), "xyz"[i], lean


def _world_direction(d: np.ndarray) -> str:
    """``"world +y"``, or ``"world +x +y"`` for a direction between two axes."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    big = [(abs(v), i) for i, v in enumerate(d) if abs(v) > 0.2]
    if max(big)[0] > 0.985:
        big = [max(big)]
    return "world " + " ".join(("+" if d[i] > 0 else "-") + "xyz"[i] for _, i in sorted(
        big, key=lambda t: t[1]))


def _height_note(frame: PlaneFrame, lo_mm: float, hi_mm: float, origin_mm: float) -> str:
    if frame.kind in AXIS_FRAMES:
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
    tilt, axis, lean = _tilt(part.pose, frame.normal)
    notes = [_height_note(frame, lo, hi, origin)]
    if tilt > 0.5:
        notes.append(f"tilt {tilt:.1f}° out of plane: its local {axis} axis leans towards "
                     f"{_world_direction(lean)} (dashed arrow)")
    if part.fall is not None:
        notes.append(f"falls towards {_world_direction(part.fall)} (solid arrow)")
    return lo, origin, tilt, notes


def _arrow_items(start, direction, length, dashed=False) -> list[PathItem]:
    """An arrow from ``start`` along the unit ``direction`` (drawing mm)."""
    d = np.asarray(direction, float)
    tip = np.asarray(start, float) + length * d
    side = np.array([-d[1], d[0]])
    dash = (1.0, 0.8) if dashed else ()
    return [PathItem((np.array([start, tip - 1.5 * d]),), closed=False, width=0.3, dash=dash,
                     cls="arrow"),
            PathItem((np.array([tip, tip - 2.2 * d + 0.9 * side, tip - 2.2 * d - 0.9 * side]),),
                     fill=(0.0, 0.0, 0.0), stroke=None, cls="arrow")]


# --- device-independent items -------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PathItem:
    """Rings of points, drawing mm, stroked and/or filled (even-odd: holes stay holes)."""

    rings: tuple[np.ndarray, ...]  # (k, 2) drawing mm each
    closed: bool = True
    fill: tuple[float, float, float] | None = None
    stroke: tuple[float, float, float] | None = (0.0, 0.0, 0.0)
    width: float = 0.2  # mm
    dash: tuple[float, ...] = ()  # mm
    cls: str = ""  # SVG class / id hint
    ident: str = ""


@dataclass(frozen=True)
class TextItem:
    """One line of text at a baseline point, drawing mm."""

    x: float
    y: float  # baseline, drawing mm (v up)
    text: str
    size: float  # mm
    bold: bool = False
    anchor: str = "start"  # start | middle | end
    colour: tuple[float, float, float] = (0.0, 0.0, 0.0)


def fill_colours(outlines, gap_mm: float = 2.0) -> list[tuple[float, float, float]]:
    """A fill colour per outline (in order): the palette in turn, skipping colours of
    earlier outlines within ``gap_mm``, so a part never merges into one it touches."""
    chosen: list[int] = []
    for k, geom in enumerate(outlines):
        near = {chosen[j] for j in range(k) if geom.distance(outlines[j]) < gap_mm}
        pick = next((c % len(PALETTE) for c in range(k, k + len(PALETTE))
                     if c % len(PALETTE) not in near), k % len(PALETTE))
        chosen.append(pick)
    return [PALETTE[c] for c in chosen]


def _rings(geom) -> list[np.ndarray]:
    rings = []
    for g in getattr(geom, "geoms", [geom]):
        rings.append(np.asarray(g.exterior.coords)[:-1])
        rings.extend(np.asarray(r.coords)[:-1] for r in g.interiors)
    return rings


def _text_items(box, lines) -> list[TextItem]:
    x0, _, _, y1 = box
    items, top = [], 0.5
    for text, size, bold in lines:
        top += 1.25 * size
        items.append(TextItem(x0 + 0.5, y1 - top + 0.3 * size, text, size, bold))
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
class Drawing:
    """A template's drawing: items in drawing order, its extent and the assembly map's items."""

    items: tuple  # PathItem | TextItem, in drawing order
    extent: tuple[float, float, float, float]  # u0, v0, u1, v1 mm
    minimap: tuple  # PathItem items for the assembly map (no text)
    ropes: tuple[RopeOutline, ...] = ()


def build_drawing(parts, base_planes, frame: PlaneFrame, *, geoms=None, avoid=(),
                  inside=None, frames=(), ropes=()) -> tuple[Drawing, tuple[PartOutline, ...]]:
    """The drawing of posed parts on a plane, and each part as drawn (in placement order).

    ``geoms`` are the parts' silhouettes when already known (in placement order); ``avoid``
    and ``inside`` steer the labels (see :func:`rgmcad.printing.labels.place_labels`);
    ``frames`` (:class:`rgmcad.printing.inputs.FrameNote`) are marked at their origins with
    their tolerances; ``ropes`` (:class:`rgmcad.printing.ropes.PlacedRope`) are drawn along
    their paths, labelled with the length to cut.
    Raises ``ValueError`` naming a part whose mesh projects to nothing on the plane.
    """
    parts = sorted(parts, key=lambda p: (p.order, p.name))
    outlines, infos, sizes, line_sets = [], [], [], []
    for k, p in enumerate(parts):
        try:
            geom = geoms[k] if geoms is not None else silhouette(p.vertices, p.faces, frame)
        except ValueError as exc:
            raise ValueError(f"part {p.name!r}: {exc}") from None
        lo, origin, tilt, notes = _part_notes(p, frame)
        lines = label_lines(p, notes)
        outlines.append(geom)
        infos.append((lo, origin, tilt, notes))
        line_sets.append(lines)
        sizes.append(block_size(lines))
    marks = [Point(*frame.to_drawing(f.origin)[0]).buffer(2.0) for f in frames]
    frame_lines = [[(f.notes[0], NOTE_MM, True), *((n, NOTE_MM, False) for n in f.notes[1:])]
                   for f in frames]
    paths = [rope_path(r, frame) for r in ropes]
    lines_of_ropes = [rope_lines(r) for r in ropes]
    boxes = place_labels(outlines + marks + [LineString(p).buffer(POINT_MM_PAD) for p in paths],
                         sizes + [block_size(x) for x in frame_lines + lines_of_ropes],
                         avoid, inside)
    boxes, frame_boxes, rope_boxes = (boxes[:len(outlines)], boxes[len(outlines):len(
        outlines) + len(marks)], boxes[len(outlines) + len(marks):])

    colours = fill_colours(outlines)
    fills, strokes, texts, leaders, arrows = [], [], [], [], []
    results = []
    for k, (p, geom) in enumerate(zip(parts, outlines, strict=True)):
        rgb = colours[k]
        rings = tuple(_rings(geom))
        ident = f"part-{k + 1}"
        fills.append(PathItem(rings, fill=rgb, stroke=None, cls="part-fill", ident=ident))
        strokes.append(PathItem(rings, width=OUTLINE_MM, cls="part-outline", ident=ident + "-o"))
        box = boxes[k]
        texts += _text_items(box, line_sets[k])
        pb, po = nearest_points(shapely_box(*box), geom)
        if pb.distance(po) > 0.8:
            leaders.append(
                PathItem((np.array([[pb.x, pb.y], [po.x, po.y]]),), closed=False,
                      stroke=(0.35, 0.35, 0.35), width=0.15, cls="leader")
            )
        c = np.array(geom.centroid.coords[0])
        lo, origin, tilt, notes = infos[k]
        for direction, dashed in ((p.fall, False), (_tilt(p.pose, frame.normal)[2], True)):
            if direction is None or (dashed and tilt <= 0.5):
                continue
            d = np.array([direction @ frame.u_axis, direction @ frame.v_axis])
            if np.linalg.norm(d) > 1e-6:
                d = d / np.linalg.norm(d)
                arrows += _arrow_items(c - 2.0 * d, d, 9.0, dashed)
        results.append(
            PartOutline(p.name, p.order, geom, c, frame.to_world(c)[0], lo, origin, tilt,
                        tuple(notes), rgb, box, tuple(p.tolerances))
        )

    for mark, box, lines in zip(marks, frame_boxes, frame_lines, strict=True):
        o = np.array(mark.centroid.coords[0])
        arrows.append(PathItem((np.asarray(mark.exterior.coords)[:-1],), width=0.3,
                               cls="frame"))
        for d in ((1.0, 0.0), (0.0, 1.0)):
            arrows.append(PathItem((np.array([o - 3.0 * np.array(d), o + 3.0 * np.array(d)]),),
                                   closed=False, width=0.3, cls="frame"))
        texts += _text_items(box, lines)
        pb, po = nearest_points(shapely_box(*box), mark)
        leaders.append(PathItem((np.array([[pb.x, pb.y], [po.x, po.y]]),), closed=False,
                                stroke=(0.35, 0.35, 0.35), width=0.15, cls="leader"))
    drawn_ropes, rope_strokes = [], []
    for rope, path, box, lines in zip(ropes, paths, rope_boxes, lines_of_ropes, strict=True):
        ident = f"rope-{rope.name}"
        rope_strokes.append(PathItem((path,), closed=False, stroke=ROPE_RGB, width=ROPE_MM,
                                     cls="rope", ident=ident))
        rope_strokes += [PathItem((point_ring(p),), stroke=ROPE_RGB, width=0.3,
                                  cls="rope-point") for p in path]
        texts += _text_items(box, lines)
        pb, po = nearest_points(shapely_box(*box), LineString(path))
        leaders.append(PathItem((np.array([[pb.x, pb.y], [po.x, po.y]]),), closed=False,
                                stroke=(0.35, 0.35, 0.35), width=0.15, cls="leader"))
        drawn_ropes.append(RopeOutline(rope, path, box))
    bounds = np.array([g.bounds for g in outlines + marks]
                      + [(*p.min(0), *p.max(0)) for p in paths]
                      + list(boxes) + list(frame_boxes) + list(rope_boxes))
    pad = 5.0
    extent = (bounds[:, 0].min() - pad, bounds[:, 1].min() - pad,
              bounds[:, 2].max() + pad, bounds[:, 3].max() + pad)

    refs = []
    for name, seg in _plane_lines(frame, base_planes, extent):
        refs.append(PathItem((seg,), closed=False, stroke=(0.3, 0.3, 0.3), width=0.2,
                          dash=(6.0, 1.5, 1.0, 1.5), cls="base-plane"))
        a, b = seg[0], seg[-1]
        ang = math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))
        if -90 <= ang <= 90:
            start = a
        else:
            start = b
        texts.append(TextItem(float(start[0]) + 2.0, float(start[1]) + 0.8,
                           f"{name} (base plane)", NOTE_MM, colour=(0.3, 0.3, 0.3)))
    u0, v0, u1, v1 = extent
    ou, ov = frame.to_drawing(np.zeros(3))[0]  # the world origin, projected
    if u0 + 5 < ou < u1 - 15 and v0 + 5 < ov < v1 - 15:
        o = np.array([ou, ov])
        for d, name, at in ((np.array([1.0, 0.0]), _axis_name(frame.u_axis), (11.0, -0.8)),
                            (np.array([0.0, 1.0]), _axis_name(frame.v_axis), (1.0, 10.5))):
            tip = o + 10.0 * d
            side = np.array([-d[1], d[0]])
            refs.append(PathItem((np.array([o, tip]),), closed=False, width=0.2, cls="origin"))
            refs.append(PathItem((np.array([tip, tip - 1.5 * d + 0.6 * side,
                                         tip - 1.5 * d - 0.6 * side]),), fill=(0, 0, 0),
                              stroke=None, cls="origin"))
            if name:
                texts.append(TextItem(ou + at[0], ov + at[1], name, NOTE_MM))
        texts.append(TextItem(ou + 0.8, ov - 3.0, "world origin", NOTE_MM))

    items = tuple(fills + strokes + refs + rope_strokes + arrows + leaders + texts)
    minimap = tuple(fills + strokes + rope_strokes)
    return Drawing(items, extent, minimap, tuple(drawn_ropes)), tuple(results)
