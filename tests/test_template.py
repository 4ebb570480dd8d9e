"""Round trips: layout -> template PDF/SVG -> rendered pages -> detected marks and outlines."""

from __future__ import annotations

import math
import re
import weakref
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pypdfium2 as pdfium
import pytest
import trimesh
from shapely.affinity import rotate, translate
from shapely.geometry import Point, Polygon

from rgmcad.printing.inputs import BasePlane, PlacedPart
from rgmcad.printing.plane import resolve_plane
from rgmcad.printing.sheets import sheet_marks
from rgmcad.printing.template import make_template
from rgmcad.printing.tiling import grid_size

DPI = 300
PX_PER_MM = DPI / 25.4
CANVAS_PX_PER_MM = 8.0

# Layout constants as documented (recomputed here, not imported, on purpose).
MARGIN, BAND, TAG_SIDE, TAG_BLACK = 10.0, 22.0, 20.0, 16.0
PAPER = {"a4": (210.0, 297.0), "letter": (215.9, 279.4), "a3": (297.0, 420.0)}

L_PROFILE = Polygon([(0, 0), (0.08, 0), (0.08, 0.02), (0.02, 0.02), (0.02, 0.06), (0, 0.06)])
U_PROFILE = Polygon([(0, 0), (0.07, 0), (0.07, 0.05), (0.055, 0.05), (0.055, 0.015),
                     (0.015, 0.015), (0.015, 0.05), (0, 0.05)])


# --- scenes ---------------------------------------------------------------------------------------


def _part(mesh, pose, name, order, tolerances=()):
    m = mesh.copy()
    m.apply_transform(pose)
    return PlacedPart(name, order, np.asarray(m.vertices), np.asarray(m.faces), pose,
                      tuple(tolerances))


def _pose(rotation=None, offset=(0, 0, 0)):
    m = np.eye(4)
    m[:3, :3] = np.eye(3) if rotation is None else rotation
    m[:3, 3] = offset
    return m


def _rz(deg):
    return trimesh.transformations.rotation_matrix(math.radians(deg), [0, 0, 1])[:3, :3]


def _rx(deg):
    return trimesh.transformations.rotation_matrix(math.radians(deg), [1, 0, 0])[:3, :3]


def _ry(deg):
    return trimesh.transformations.rotation_matrix(math.radians(deg), [0, 1, 0])[:3, :3]


def floor_scene():
    """Parts on a floor (z = 0, normal +Z) and their expected silhouette centroids, world m.

    Seen from above: drawing (u, v) mm = 1000 (x, y).
    """
    parts, expected = [], {}
    # 1: box 100 x 40 x 20 mm turned 30 degrees about Z
    p = _pose(_rz(30), (0.06, 0.08, 0.01))
    parts.append(_part(trimesh.creation.box([0.1, 0.04, 0.02]), p, "box", 1,
                       ("x ± 3 mm", "y ± 3 mm")))
    expected["box"] = (0.06, 0.08)
    # 2: cylinder r 20 mm standing
    parts.append(_part(trimesh.creation.cylinder(0.02, 0.05, sections=96),
                       _pose(offset=(0.26, 0.05, 0.025)), "cyl", 2))
    expected["cyl"] = (0.26, 0.05)
    # 3: an L extruded along Z: the foot points to +X, the bar to +Y
    parts.append(_part(trimesh.creation.extrude_polygon(L_PROFILE, 0.01),
                       _pose(offset=(0.19, 0.17, 0.0)), "ell", 3, ("heading ± 2°",)))
    expected["ell"] = tuple(np.array(translate(L_PROFILE, 0.19, 0.17).centroid.coords[0]))
    # 4: a U-shaped wall (open towards +Y), turned 90 degrees
    u = rotate(U_PROFILE, 90, origin=(0, 0), use_radians=False)
    parts.append(_part(trimesh.creation.extrude_polygon(U_PROFILE, 0.03),
                       _pose(_rz(90), (0.05, 0.2, 0.0)), "wall", 4))
    expected["wall"] = tuple(np.array(translate(u, 0.05, 0.2).centroid.coords[0]))
    # 5: a plate 50 mm above the floor, tilted 15 degrees about X (the outline cannot show it)
    parts.append(_part(trimesh.creation.box([0.06, 0.03, 0.01]),
                       _pose(_rx(15), (0.3, 0.3, 0.055)), "plate", 5, ("roll ± 2°",)))
    expected["plate"] = (0.3, 0.3)
    # 6: a washer: its hole must stay a hole
    ring = Point(0, 0).buffer(0.025, 64).difference(Point(0, 0).buffer(0.012, 64))
    parts.append(_part(trimesh.creation.extrude_polygon(ring, 0.005),
                       _pose(offset=(0.33, 0.13, 0.0)), "washer", 6))
    expected["washer"] = (0.33, 0.13)
    floor = BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))
    return parts, [floor], expected


def board_scene():
    """Parts pinned to a board (y = 0, normal +Y) above a floor (z = 0).

    Seen from the front (from +Y): drawing (u, v) mm = 1000 (-x, z).
    """
    parts, expected = [], {}
    t = 0.012
    # 1: ramp: a box turned 10 degrees in the board's plane
    parts.append(_part(trimesh.creation.box([0.16, t, 0.012]),
                       _pose(_ry(10), (0.05, t / 2, 0.26)), "ramp", 1, ("z ± 2 mm",)))
    expected["ramp"] = (0.05, 0.26)
    # 2: track: a U channel along X, groove opening up (+Z), seen from the front: a rectangle
    r = np.column_stack([[0, 1, 0], [0, 0, 1], [1, 0, 0]]).astype(float)  # a->Y, b->Z, axis->X
    prof = Polygon([(0, 0), (0.025, 0), (0.025, 0.015), (0.021, 0.015), (0.021, 0.004),
                    (0.004, 0.004), (0.004, 0.015), (0, 0.015)])
    parts.append(_part(trimesh.creation.extrude_polygon(prof, 0.2), _pose(r, (-0.14, 0, 0.15)),
                       "track", 2, ("x ± 3 mm", "pitch ± 1°")))
    expected["track"] = (-0.14 + 0.1, 0.15 + 0.0075)
    # 3: a disc on an axle along Y
    parts.append(_part(trimesh.creation.cylinder(0.03, 0.04, sections=96),
                       _pose(_rx(90), (0.13, 0.02, 0.09)), "disc", 3))
    expected["disc"] = (0.13, 0.09)
    # 4: an L in the board's plane: foot towards +X, bar towards +Z (extruded towards +Y)
    r = np.column_stack([[1, 0, 0], [0, 0, 1], [0, -1, 0]]).astype(float)  # a->X, b->Z, c->-Y
    parts.append(_part(trimesh.creation.extrude_polygon(L_PROFILE, t), _pose(r, (-0.1, t, 0.02)),
                       "ell", 4))
    expected["ell"] = tuple(np.array(translate(L_PROFILE, -0.1, 0.02).centroid.coords[0]))
    # 5: a plate tilted 20 degrees out of the board (about X), its back edge on the board
    half_y = 0.5 * (0.02 * math.cos(math.radians(20)) + 0.015 * math.sin(math.radians(20)))
    parts.append(_part(trimesh.creation.box([0.08, 0.02, 0.015]),
                       _pose(_rx(20), (-0.05, half_y, 0.32)), "flap", 5))
    expected["flap"] = (-0.05, 0.32)
    planes = [BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0])),
              BasePlane("board", np.zeros(3), np.array([0.0, 1.0, 0.0]))]
    return parts, planes, expected


# --- rendering and measuring ----------------------------------------------------------------------


def render(pdf_path):
    pdf = pdfium.PdfDocument(str(pdf_path))
    pages = [np.asarray(pdf[i].render(scale=DPI / 72).to_pil().convert("RGB"))
             for i in range(len(pdf))]
    pdf.close()
    return pages


def _aruco(refine):
    params = cv2.aruco.DetectorParameters()
    params.cornerRefinementMethod = refine
    return cv2.aruco.ArucoDetector(
        cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11), params)


def detect(rgb):
    """{id: (4, 2) corners px, pixel centres at integers}.

    Found on a quarter-size copy, then refined (AprilTag corner refinement, whose corners are
    0.5 px off) in a crop of the full page around each mark.
    """
    grey = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)
    small = cv2.resize(grey, None, fx=0.25, fy=0.25, interpolation=cv2.INTER_AREA)
    corners, ids, _ = _aruco(cv2.aruco.CORNER_REFINE_NONE).detectMarkers(small)
    if ids is None:
        return {}
    out = {}
    for c, i in zip(corners, ids.ravel(), strict=True):
        c = (c.reshape(4, 2) + 0.5) * 4 - 0.5
        x0, y0 = (c.min(0) - 60).astype(int).clip(0)
        x1, y1 = (c.max(0) + 60).astype(int)
        crop = np.ascontiguousarray(grey[y0:y1, x0:x1])
        fine, fids, _ = _aruco(cv2.aruco.CORNER_REFINE_APRILTAG).detectMarkers(crop)
        assert fids is not None and int(i) in fids.ravel()
        j = list(fids.ravel()).index(int(i))
        out[int(i)] = fine[j].reshape(4, 2) - 0.5 + (x0, y0)
    return out


def expected_ids(label):
    """Tag ids of a page, from the documented scheme: 4 * slot + corner."""
    if label == "map":
        slot = 0
    else:
        slot = 1 + (ord(label[0]) - ord("A")) + 12 * (int(label[1:]) - 1)
    return {4 * slot + c for c in range(4)}


# Caches keyed by id(): an entry goes when its object does, since a freed page's id can be
# handed to a new page, which would otherwise read the old page's marks.
_DETECTED: dict[tuple, object] = {}
_STITCHED: dict[tuple, object] = {}


def _cached(cache, obj, extra, make):
    key = (id(obj), extra)
    if key not in cache:
        cache[key] = make()
        weakref.finalize(obj, cache.pop, key, None)
    return cache[key]


def detect_page(pages, index):
    """Marks of page ``index`` (0-based), detected once per test module."""
    return _cached(_DETECTED, pages[index], None, lambda: detect(pages[index]))


def stitch(result, pages):
    """Warp every tiled sheet, by its detected marks, onto one canvas in drawing mm."""
    return _cached(_STITCHED, result, None, lambda: _stitch(result, pages))


def _stitch(result, pages):
    u0, v0, u1, v1 = result.extent_mm
    k = CANVAS_PX_PER_MM
    size = (int(math.ceil((u1 - u0) * k)), int(math.ceil((v1 - v0) * k)))
    canvas = np.full((size[1], size[0], 3), 255, np.uint8)
    to_canvas = np.array([[k, 0, -u0 * k], [0, -k, v1 * k], [0, 0, 1.0]])
    for sheet in result.sheets:
        img = pages[sheet.page - 1]
        marks = detect_page(pages, sheet.page - 1)
        assert set(marks) == set(sheet.tag_ids)
        px = np.concatenate([marks[i] for i in sheet.tag_ids])
        mm = np.concatenate([sheet.tag_corners_mm[i] for i in sheet.tag_ids])
        h_px_mm, _ = cv2.findHomography(px, mm, 0)
        x0, y0, x1, y1 = sheet.window_mm
        ru0, rv0, ru1, rv1 = sheet.region_mm
        # sheet mm (y down) -> drawing mm (v up): a translation and a flip of y, no mirror
        page_to_drawing = np.array([[1.0, 0, ru0 - x0], [0, -1.0, rv1 + y0], [0, 0, 1]])
        assert np.allclose(page_to_drawing, sheet.page_to_drawing())
        m = to_canvas @ page_to_drawing @ h_px_mm
        warped = cv2.warpPerspective(img, m, size, flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=(255, 255, 255))
        c0, c1 = int(round((ru0 - u0) * k)), int(round((ru1 - u0) * k))
        r0, r1 = int(round((v1 - rv1) * k)), int(round((v1 - rv0) * k))
        c0, r0 = max(c0, 0), max(r0, 0)
        canvas[r0:r1, c0:c1] = np.minimum(canvas[r0:r1, c0:c1], warped[r0:r1, c0:c1])
    return canvas


_MASKS: dict = {}


def part_mask(canvas, rgb):
    return _cached(_MASKS, canvas, tuple(rgb), lambda: _part_mask(canvas, rgb))


def _part_mask(canvas, rgb):
    target = np.array([round(255 * c) for c in rgb], np.int16)
    mask = (np.abs(canvas.astype(np.int16) - target).max(axis=2) <= 12).astype(np.uint8)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask)
    keep = np.zeros_like(mask)
    for i in range(1, n):
        if stats[i, cv2.CC_STAT_AREA] > 200:
            keep[lab == i] = 1
    return keep


def mask_centroid_mm(result, mask):
    ys, xs = np.nonzero(mask)
    u0, _, _, v1 = result.extent_mm
    return np.array([u0 + xs.mean() / CANVAS_PX_PER_MM, v1 - ys.mean() / CANVAS_PX_PER_MM])


@pytest.fixture(scope="module")
def floor(tmp_path_factory):
    parts, planes, expected = floor_scene()
    out = tmp_path_factory.mktemp("floor")
    result = make_template(parts, planes, out, paper="a4", orientation="portrait",
                           title="floor test")
    return result, render(result.pdf), expected


@pytest.fixture(scope="module")
def board(tmp_path_factory):
    parts, planes, expected = board_scene()
    out = tmp_path_factory.mktemp("board")
    result = make_template(parts, planes, out, paper="a4", title="board test")
    return result, render(result.pdf), expected


@pytest.fixture(scope="module", params=["floor", "board"])
def layout(request):
    return request.getfixturevalue(request.param), request.param


def world_to_drawing(kind, xy):
    x, y = xy
    return np.array([1000 * x, 1000 * y]) if kind == "floor" else np.array([-1000 * x, 1000 * y])


# --- tests ----------------------------------------------------------------------------------------


def test_planes_chosen_automatically():
    parts, planes, _ = floor_scene()
    assert resolve_plane(parts, planes).kind == "floor"
    parts, planes, _ = board_scene()
    frame = resolve_plane(parts, planes)
    assert frame.kind == "board" and frame.base == "board"
    # seen from the front (+Y): up is +Z, right is -X, and u x v points at the viewer
    assert np.allclose(frame.v_axis, [0, 0, 1]) and np.allclose(frame.u_axis, [-1, 0, 0])
    # no base plane, a layout flat in y: the xz plane
    assert resolve_plane(parts, []).kind == "xz"
    with pytest.raises(ValueError, match="choose one of"):
        resolve_plane(parts, planes, "ceiling")


@pytest.mark.parametrize("name", ["xy", "xz", "yz", "floor", "board"])
def test_frames_are_right_handed_and_upright(name):
    parts, planes, _ = board_scene()
    f = resolve_plane(parts, planes, name)
    assert np.allclose(np.cross(f.u_axis, f.v_axis), f.normal)
    if name != "xy" and name != "floor":
        assert f.v_axis[2] > 0.99  # world up is up on paper


def test_marks_found_with_right_ids_and_spacing(layout):
    (result, pages, _), kind = layout
    worst = 0.0
    for sheet in (result.map_sheet, *result.sheets):
        marks = detect_page(pages, sheet.page - 1)
        assert set(marks) == expected_ids(sheet.label) == set(sheet.tag_ids)
        centres = {i: c.mean(0) / PX_PER_MM for i, c in marks.items()}
        planned = result.tag_centres[sheet.label]
        ids = sorted(centres)
        for a in ids:
            for b in ids:
                if a < b:
                    d = np.linalg.norm(centres[a] - centres[b])
                    d0 = np.linalg.norm(np.subtract(planned[a], planned[b]))
                    worst = max(worst, abs(d - d0))
        # planned centres sit at the printable area's corners
        w, h = sheet.size_mm
        half = MARGIN + TAG_SIDE / 2
        expect = {(half, half), (w - half, half), (w - half, h - half), (half, h - half)}
        got = {tuple(np.round(c, 6)) for c in planned.values()}
        assert got == {tuple(np.round(e, 6)) for e in expect}
    assert worst < 0.2, f"{kind}: tag spacing error {worst:.3f} mm"


def _crossing(profile):
    """Sub-pixel index where a white-to-dark profile crosses half way."""
    p = profile.astype(float)
    mid = (p[:4].mean() + p[-4:].mean()) / 2
    i = int(np.nonzero(p < mid)[0][0])
    return i - 1 + (p[i - 1] - mid) / (p[i - 1] - p[i])


def _square_side_mm(grey, side_mm):
    """Measure a square of nominal ``side_mm`` across its outer edges in a 300 dpi raster,
    as a ruler laid on the printed edges would."""
    _, binary = cv2.threshold(grey, 128, 255, cv2.THRESH_BINARY_INV)
    contours, _ = cv2.findContours(binary, cv2.RETR_LIST, cv2.CHAIN_APPROX_SIMPLE)
    nominal = side_mm * PX_PER_MM
    found = [cv2.minAreaRect(c) for c in contours]
    found = [r for r in found if all(abs(v - nominal) < 0.05 * nominal for v in r[1])]
    assert found, f"no {side_mm} mm square found"
    (cx, cy), (w, h), _ = max(found, key=lambda r: r[1][0])  # the outer edge
    x0, y0, x1, y1 = cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2
    r = 10
    rows = np.arange(int(y0 + 0.3 * h), int(y1 - 0.3 * h))
    cols = np.arange(int(x0 + 0.3 * w), int(x1 - 0.3 * w))
    a, b = int(x0) - r, int(x1) + r
    left = np.mean([a + _crossing(grey[y, a:a + 2 * r]) for y in rows])
    right = np.mean([b - _crossing(grey[y, b - 2 * r:b + 1][::-1]) for y in rows])
    a, b = int(y0) - r, int(y1) + r
    top = np.mean([a + _crossing(grey[a:a + 2 * r, x]) for x in cols])
    bottom = np.mean([b - _crossing(grey[b - 2 * r:b + 1, x][::-1]) for x in cols])
    return (right - left) / PX_PER_MM, (bottom - top) / PX_PER_MM


def test_test_squares_measure_true_across_their_outer_edges(floor):
    result, pages, _ = floor
    grey = cv2.cvtColor(pages[result.map_sheet.page - 1], cv2.COLOR_RGB2GRAY)
    w, h = _square_side_mm(grey, 100.0)
    assert abs(w - 100.0) < 0.1 and abs(h - 100.0) < 0.1, (w, h)
    w, h = _square_side_mm(grey, 25.4)
    assert abs(w - 25.4) < 0.1 and abs(h - 25.4) < 0.1, (w, h)
    doc = pdfium.PdfDocument(str(result.pdf))
    text = doc[result.map_sheet.page - 1].get_textpage().get_text_range()
    doc.close()
    assert "OUTER edges" in text  # the sheet says which edge is the measure


def test_outlines_land_at_world_positions(layout):
    (result, pages, expected), kind = layout
    canvas = stitch(result, pages)
    worst = 0.0
    for part in result.parts:
        mask = part_mask(canvas, part.fill_rgb)
        assert mask.sum() > 0, part.name
        got = mask_centroid_mm(result, mask)
        want = world_to_drawing(kind, expected[part.name])
        err = float(np.linalg.norm(got - want))
        worst = max(worst, err)
        assert err < 0.5, f"{kind} {part.name}: centroid off by {err:.3f} mm"
        # the result's own numbers agree (drawing mm and world metres)
        assert np.linalg.norm(part.centroid_mm - want) < 0.05
        assert np.linalg.norm(result.frame.to_drawing(part.centroid_world)[0] - want) < 0.05
    assert worst < 0.5
    if kind == "floor":  # the washer's hole is not filled
        washer = next(p for p in result.parts if p.name == "washer")
        u0, _, _, v1 = result.extent_mm
        cx = int(round((330.0 - u0) * CANVAS_PX_PER_MM))
        cy = int(round((v1 - 130.0) * CANVAS_PX_PER_MM))
        assert part_mask(canvas, washer.fill_rgb)[cy - 40:cy + 40, cx - 40:cx + 40].sum() == 0
        assert (canvas[cy - 40:cy + 40, cx - 40:cx + 40] > 250).all()


def _handedness(mask):
    """Signs of (centroid - bbox centre) in image coordinates (x right, y down)."""
    ys, xs = np.nonzero(mask)
    cx, cy = xs.mean(), ys.mean()
    bx, by = (xs.min() + xs.max()) / 2, (ys.min() + ys.max()) / 2
    return np.sign(cx - bx), np.sign(cy - by)


def test_drawing_is_not_mirrored(layout):
    (result, pages, _), kind = layout
    canvas = stitch(result, pages)
    ell = next(p for p in result.parts if p.name == "ell")
    sx, sy = _handedness(part_mask(canvas, ell.fill_rgb))
    # the L's corner (where its mass is) is at the bottom; its foot points to world +X:
    # right on the floor seen from above, left on a board with normal +Y seen from the front
    assert sy > 0
    assert sx == (-1 if kind == "floor" else 1)


def test_xz_plane_is_seen_from_minus_y(tmp_path):
    parts, _, _ = board_scene()
    result = make_template(parts, [], tmp_path, plane="xz", paper="a3")
    ell = next(p for p in result.parts if p.name == "ell")
    c = np.array(ell.outline.centroid.coords[0])
    b = ell.outline.bounds
    assert c[0] < (b[0] + b[2]) / 2  # foot to the right: mass on the left
    assert c[1] < (b[1] + b[3]) / 2  # corner at the bottom


def _svg_rings(d):
    rings = []
    for chunk in re.findall(r"M([^MZ]+)Z", d):
        pts = [tuple(map(float, p.split(","))) for p in chunk.split()]
        rings.append(pts)
    return rings


def test_svg_in_mm_with_the_pdf_geometry(layout):
    (result, pages, expected), kind = layout
    root = ET.parse(result.svg).getroot()
    assert root.get("width").endswith("mm") and root.get("height").endswith("mm")
    w, h = float(root.get("width")[:-2]), float(root.get("height")[:-2])
    vb = [float(v) for v in root.get("viewBox").split()]
    assert vb[:2] == [0.0, 0.0] and abs(vb[2] - w) < 1e-3 and abs(vb[3] - h) < 1e-3
    u0, v0, u1, v1 = result.extent_mm
    assert abs(w - (u1 - u0)) < 1e-3 and abs(h - (v1 - v0)) < 1e-3
    ns = {"s": "http://www.w3.org/2000/svg"}
    canvas = stitch(result, pages)
    for k, part in enumerate(result.parts, start=1):
        el = root.find(f".//s:path[@id='part-{k}']", ns)
        rings = _svg_rings(el.get("d"))
        # even-odd: the exterior less the holes; back to drawing mm (u = x + u0, v = v1 - y)
        geom = Polygon(rings[0])
        for r in rings[1:]:
            geom = geom.symmetric_difference(Polygon(r))
        cx, cy = geom.centroid.coords[0]
        svg_centroid = np.array([cx + u0, v1 - cy])
        assert np.linalg.norm(svg_centroid - part.centroid_mm) < 0.01
        assert abs(geom.area - part.outline.area) < 0.01
        pdf_centroid = mask_centroid_mm(result, part_mask(canvas, part.fill_rgb))
        assert np.linalg.norm(svg_centroid - pdf_centroid) < 0.5, part.name
        assert np.linalg.norm(svg_centroid - world_to_drawing(kind, expected[part.name])) < 0.05


def test_a_part_placed_from_the_svg_header_alone_lands_on_its_outline(layout):
    # as a user reads the file: the <desc> says where world points are in SVG units
    (result, _, expected), kind = layout
    root = ET.parse(result.svg).getroot()
    desc = root.find("{http://www.w3.org/2000/svg}desc").text
    got = re.search(r"SVG x = u ([+-]) ([\d.]+), y = ([\d.]+) - v; u runs along world "
                    r"([+-][xyz]) and v along world ([+-][xyz]), from the world point "
                    r"\(([^)]*)\) mm", desc)
    assert got, desc
    sign, shift, top, u_axis, v_axis, origin = got.groups()
    origin = np.array([float(c) for c in origin.split(",")])

    def along(axis, world_mm):
        return (1 if axis[0] == "+" else -1) * (world_mm - origin)["xyz".index(axis[1])]

    ns = {"s": "http://www.w3.org/2000/svg"}
    for k, part in enumerate(result.parts, start=1):
        a, b = expected[part.name]  # world (x, y) on the floor, (x, z) on the board
        world = np.array([a, b, 0.0] if kind == "floor" else [a, 0.0, b]) * 1000
        u, v = along(u_axis, world), along(v_axis, world)
        x, y = u + (float(shift) if sign == "+" else -float(shift)), float(top) - v
        rings = _svg_rings(root.find(f".//s:path[@id='part-{k}']", ns).get("d"))
        geom = Polygon(rings[0])
        for r in rings[1:]:
            geom = geom.symmetric_difference(Polygon(r))
        assert np.linalg.norm(np.array(geom.centroid.coords[0]) - [x, y]) < 0.05, part.name


def test_notes_heights_tilts_and_tolerances(floor, board):
    for result, _, _ in (floor, board):
        text = ""
        doc = pdfium.PdfDocument(str(result.pdf))
        for i in range(len(doc)):
            text += doc[i].get_textpage().get_text_range() + "\n"
        doc.close()
        assert "Print at 100 % / actual size" in text
        for part in result.parts:
            assert f"{part.order}. {part.name}" in text
            for tol in part.tolerances:
                assert tol in text
        for label in result.sheet_labels:
            assert label in text
    fr, br = floor[0], board[0]
    plate = next(p for p in fr.parts if p.name == "plate")
    assert abs(plate.tilt_deg - 15.0) < 0.01
    assert abs(plate.lowest_mm - (55 - 0.5 * (30 * math.sin(math.radians(15))
                                              + 10 * math.cos(math.radians(15))))) < 0.01
    assert any("tilt 15.0°" in n for n in plate.notes)
    flap = next(p for p in br.parts if p.name == "flap")
    assert abs(flap.tilt_deg - 20.0) < 0.01 and any("tilt 20.0°" in n for n in flap.notes)
    assert all(p.tilt_deg < 0.01 for p in br.parts if p.name != "flap")
    assert abs(next(p for p in fr.parts if p.name == "box").lowest_mm) < 1e-6


def _expected_grid(w, h, paper, orientation, overlap):
    pw, ph = PAPER[paper] if orientation == "portrait" else PAPER[paper][::-1]
    ww, wh = pw - 2 * MARGIN, ph - 2 * MARGIN - 2 * BAND
    cols = max(1, math.ceil((w - overlap) / (ww - overlap) - 1e-9))
    rows = max(1, math.ceil((h - overlap) / (wh - overlap) - 1e-9))
    return cols, rows, ww, wh


def test_large_drawing_tiles_into_expected_sheets(tmp_path):
    parts = []
    for i in range(6):
        x, y = 0.22 * i, 0.09 * (i % 3)
        parts.append(_part(trimesh.creation.box([0.1, 0.05, 0.02]), _pose(offset=(x, y, 0.01)),
                           f"block[{i}]", i + 1))
    floor = BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))
    for paper, orientation, overlap in (("a4", "landscape", 12.0), ("letter", "portrait", 15.0)):
        r = make_template(parts, [floor], tmp_path / f"{paper}-{orientation}", paper=paper,
                          orientation=orientation, overlap_mm=overlap)
        u0, v0, u1, v1 = r.extent_mm
        cols, rows, ww, wh = _expected_grid(u1 - u0, v1 - v0, paper, orientation, overlap)
        assert r.grid == (cols, rows) and cols * rows > 1
        assert len(r.sheets) == cols * rows == len(r.tag_centres) - 1
        assert r.sheet_labels[:2] == ("A1", "B1")
        assert len(pdfium.PdfDocument(str(r.pdf))) == r.n_pages >= 1 + cols * rows
        # neighbours share exactly the overlap, and together they cover the drawing
        for s in r.sheets:
            x0, y0, x1, y1 = s.window_mm
            assert (x0, x1 - x0, y1 - y0) == (MARGIN, ww, wh) and y0 == MARGIN + BAND
            assert s.region_mm[2] - s.region_mm[0] == pytest.approx(ww)
            right = [t for t in r.sheets if (t.col, t.row) == (s.col + 1, s.row)]
            if right:
                assert s.region_mm[2] - right[0].region_mm[0] == pytest.approx(overlap)
            below = [t for t in r.sheets if (t.col, t.row) == (s.col, s.row + 1)]
            if below:
                assert below[0].region_mm[3] - s.region_mm[1] == pytest.approx(overlap)
        assert min(s.region_mm[0] for s in r.sheets) <= u0
        assert max(s.region_mm[2] for s in r.sheets) >= u1
        assert min(s.region_mm[1] for s in r.sheets) <= v0
        assert max(s.region_mm[3] for s in r.sheets) >= v1
    # automatic paper and orientation: the fewest sheets over all choices
    r = make_template(parts, [floor], tmp_path / "auto")
    u0, v0, u1, v1 = r.extent_mm
    counts = {(p, o): math.prod(_expected_grid(u1 - u0, v1 - v0, p, o, 12.0)[:2])
              for p in PAPER for o in ("portrait", "landscape")}
    assert len(r.sheets) == min(counts.values()) == counts[(r.paper, r.orientation)]
    assert grid_size(u1 - u0, v1 - v0, r.paper, r.orientation, 12.0) == r.grid


def test_mark_layout_is_orientation_free():
    # the landscape page is the portrait page turned a quarter turn clockwise
    por = sheet_marks("a4", "portrait", 5)
    lan = sheet_marks("a4", "landscape", 5)
    for i in por:
        x, y = por[i].T
        assert np.allclose(lan[i], np.column_stack([297.0 - y, x]))
    assert sorted(por) == [20, 21, 22, 23]
    assert np.allclose(np.ptp(por[20], axis=0), [TAG_BLACK, TAG_BLACK])


def test_long_parts_list_continues_and_limits_are_explained(tmp_path):
    floor = BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))
    parts = [_part(trimesh.creation.box([0.02, 0.01, 0.04]),
                   _pose(_rz(7 * i), (0.045 * (i % 10), 0.045 * (i // 10), 0.02)), f"run[{i}]", i + 1,
                   ("x ± 3 mm", "heading ± 2°"))
             for i in range(100)]
    r = make_template(parts, [floor], tmp_path / "many", paper="a4", orientation="portrait")
    assert r.n_pages > 1 + len(r.sheets)  # the parts list runs over onto another page
    doc = pdfium.PdfDocument(str(r.pdf))
    text = "".join(doc[i].get_textpage().get_text_range() for i in range(r.n_pages - len(r.sheets)))
    # sheets are numbered after the continuation pages, and say so on their page
    assert [s.page for s in r.sheets] == list(range(r.n_pages - len(r.sheets) + 1, r.n_pages + 1))
    for s in r.sheets:
        page_text = doc[s.page - 1].get_textpage().get_text_range()
        assert f"sheet {s.label} of" in page_text and f"page {s.page};" in page_text
    doc.close()
    text = " ".join(text.split())
    for i in range(100):  # each part names the sheet(s) it is on
        m = re.search(rf"{i + 1}\. run\[{i}\] \[sheet ([A-Z0-9, ]+)\]:", text)
        assert m, f"run[{i}] not listed with its sheet"
        assert set(m.group(1).split(", ")) <= set(r.sheet_labels)
    far = [parts[0], _part(trimesh.creation.box([0.02, 0.01, 0.04]), _pose(offset=(6.0, 0, 0.02)),
                           "far", 2)]
    with pytest.raises(ValueError, match="12 x 12 sheets"):
        make_template(far, [floor], tmp_path / "far", paper="a4")
