"""A maker's assembly of a printed template: print the sheets, cut each along its printed
cut line, lay it on its neighbours as the sheet says (cut edge on their seam line, letter
pairs meeting), and check where every part's outline lands.

Nothing about where a sheet goes comes from the template's own numbers: the cut and butt
lines and the matching marks are found in the rasterised pages, as a person finds them with
their eyes. Only the first sheet is tied to the layout (the maker places it by its world
ticks), and the parts' positions in the assembled paper are compared with the layout's.
"""

from __future__ import annotations

import re

import cv2
import numpy as np
import pypdfium2 as pdfium
import pytest
import shapely
from PIL import Image
from shapely.ops import unary_union

from rgmcad.printing.check import verify_print
from rgmcad.printing.template import scene_template
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario

DPI = 150
K = DPI / 25.4  # px per mm
TOLERANCE_MM = 0.5
PAD = 100  # px of table around the assembled paper


def magenta(rgb):
    """Weight of the seam colour (magenta) per pixel: 0 on white, black and the pale fills."""
    r, g, b = (rgb[..., i].astype(np.int16) for i in range(3))
    return np.clip(np.minimum(r, b) - g - 30, 0, None).astype(np.float32)


def printed(page, scale):
    """The page as printed at ``scale`` (content scaled about the paper's centre)."""
    h, w = page.shape[:2]
    m = np.float32([[scale, 0, (1 - scale) * w / 2], [0, scale, (1 - scale) * h / 2]])
    return cv2.warpAffine(page, m, (w, h), flags=cv2.INTER_LINEAR,
                          borderValue=(255, 255, 255))


def _peak_centre(profile, i):
    lo, hi = max(0, i - 4), min(len(profile), i + 5)
    w = profile[lo:hi]
    return float((w * np.arange(lo, hi)).sum() / w.sum())


def seam_lines(m):
    """Long magenta lines of a sheet: ``{"left", "right", "top", "bottom": position px}``.

    The sheet's instruction: cut along the line at the left and top; the lines at the right
    and bottom are where the neighbours' cut edges go. ``m``: :func:`magenta` of the sheet.
    """
    h, w = m.shape
    found = {}
    for axis, (lo_name, hi_name), n in ((0, ("left", "right"), h), (1, ("top", "bottom"), w)):
        prof = (m > 40).sum(axis=axis).astype(float)
        weight = m.sum(axis=axis)
        for i in np.nonzero(prof > 0.5 * n * 0.6)[0]:
            if prof[i] < prof[max(0, i - 3):i + 4].max():
                continue
            name = lo_name if i < len(prof) / 2 else hi_name
            found.setdefault(name, _peak_centre(weight, int(i)))
    return found


def matching_marks(m, lines, side, kept):
    """Centres (px along the seam) of the matching-mark strokes beside a seam line.

    Looks in a band 2-4 mm from the line on the side the sheet keeps (``kept`` +1: towards
    larger pixel coordinates), skipping where another seam line crosses the band.
    ``m``: :func:`magenta` of the sheet.
    """
    at = lines[side]
    a, b = sorted((at + kept * 2.0 * K, at + kept * 4.0 * K))
    if side in ("left", "right"):
        prof = m[:, int(a):int(b) + 1].mean(axis=1)
        others = [lines[s] for s in ("top", "bottom") if s in lines]
    else:
        prof = m[int(a):int(b) + 1, :].mean(axis=0)
        others = [lines[s] for s in ("left", "right") if s in lines]
    for o in others:
        prof[max(0, int(o - 1.5 * K)):int(o + 1.5 * K) + 1] = 0
    on = prof > 30
    centres, i = [], 0
    while i < len(on):
        if on[i]:
            j = i
            while j < len(on) and on[j]:
                j += 1
            seg = prof[i:j]
            centres.append(float((seg * np.arange(i, j)).sum() / seg.sum()))
            i = j
        i += 1
    return np.array(centres)


def assemble(result, pages):
    """Lay the cut sheets as instructed; returns the assembled paper (RGB) and each sheet's
    offset (px) from the first sheet (which lies at ``PAD`` px from the canvas's corner)."""
    by_label = {s.label: pages[s.page - 1] for s in result.sheets}
    weights = {lab: magenta(img) for lab, img in by_label.items()}
    lines = {lab: seam_lines(m) for lab, m in weights.items()}
    offsets: dict[str, np.ndarray] = {}
    for s in result.sheets:  # row by row: every sheet goes on its left and upper neighbours
        lab = s.label
        left = f"{chr(ord(lab[0]) - 1)}{lab[1:]}" if lab[0] > "A" else None
        above = f"{lab[0]}{int(lab[1:]) - 1}" if int(lab[1:]) > 1 else None
        if left is None and above is None:
            offsets[lab] = np.zeros(2)
            continue
        guesses = []
        for nb, mine, theirs, axis in ((left, "left", "right", 0), (above, "top", "bottom", 1)):
            if nb is None:
                continue
            assert mine in lines[lab] and theirs in lines[nb], (lab, nb, lines[lab], lines[nb])
            off = np.zeros(2)
            off[axis] = offsets[nb][axis] + lines[nb][theirs] - lines[lab][mine]
            ours = matching_marks(weights[lab], lines[lab], mine, +1)
            twins = matching_marks(weights[nb], lines[nb], theirs, -1)
            assert len(ours) == len(twins) >= 2, (lab, nb, ours, twins)
            off[1 - axis] = offsets[nb][1 - axis] + float(np.mean(twins - ours))
            guesses.append(off)
        offsets[lab] = np.mean(guesses, axis=0)
        if len(guesses) == 2:  # both neighbours agree on where this sheet goes
            assert np.abs(guesses[0] - guesses[1]).max() < 0.3 * K, (lab, guesses)
    size = np.max([offsets[lab] + by_label[lab].shape[1::-1] for lab in by_label], axis=0)
    canvas = np.full((int(size[1]) + 2 * PAD, int(size[0]) + 2 * PAD, 3), 255, np.uint8)
    for s in result.sheets:
        img, off, ln = by_label[s.label], offsets[s.label], lines[s.label]
        keep = np.ones(img.shape[:2], np.uint8)
        if "left" in ln and s.col > 0:  # scissors along the line's centre
            keep[:, :int(ln["left"] + 0.5)] = 0
        if "top" in ln and s.row > 0:
            keep[:int(ln["top"] + 0.5), :] = 0
        off = off + PAD
        at = np.floor(off).astype(int)
        m = np.float32([[1, 0, off[0] - at[0]], [0, 1, off[1] - at[1]]])
        h, w = img.shape[:2]
        laid = cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR, borderValue=(255,) * 3)
        paper = cv2.warpAffine(keep, m, (w, h), flags=cv2.INTER_NEAREST) > 0
        roi = canvas[at[1]:at[1] + h, at[0]:at[0] + w]
        roi[paper] = laid[paper]
    return canvas, offsets


def canvas_px_per_mm(result, sheet):
    """Pixels per mm along x and y of a rendered page of ``sheet``."""
    w, h = sheet.size_mm
    return (int(np.ceil(w * K - 1e-6)) / w, int(np.ceil(h * K - 1e-6)) / h)


def _shift(points, boundary, search_mm):
    """Translation (mm) that lays boundary ``points`` (n, 2) on ``boundary`` (shapely):
    iterated closest points, ignoring points far from it (letters printed over a fill)."""
    t = np.zeros(2)
    reach = search_mm
    for _ in range(8):
        ends = shapely.get_coordinates(shapely.shortest_line(boundary, shapely.points(points - t)))
        r = ends[1::2] - ends[0::2]  # from the outline to each point
        keep = np.hypot(*r.T) < reach
        if keep.sum() < 10:
            break
        t += r[keep].mean(axis=0)
        reach = max(1.0, min(reach, 3 * np.abs(r[keep]).max()) / 2)
    return t


def part_errors(result, canvas, search_mm):
    """How far (mm) each part's outline in the assembled paper is from the layout's.

    The first sheet is tied to the layout (as its world ticks place it); each part's visible
    fill (its outline less the parts drawn over it) is found by colour near where the layout
    has it, and its shift measured by phase correlation with the outline rasterised from the
    layout (robust to the thin lines and letters printed over a fill).
    """
    first = result.sheets[0]
    x0, y0, _, _ = first.window_mm
    u0, _, _, v1 = first.region_mm
    # the rasteriser fits the page to whole pixels: a print scale off by under 0.1 %
    kx, ky = np.array(canvas_px_per_mm(result, first))

    def to_mm(px):
        px = np.asarray(px, float)
        px = px - PAD + 0.5
        return np.column_stack([px[:, 0] / kx - x0 + u0, v1 - (px[:, 1] / ky - y0)])

    def to_px(uv):  # drawing mm -> assembled px (centres at integers), via the first sheet
        uv = np.asarray(uv, float).reshape(-1, 2)
        return np.column_stack([(uv[:, 0] - u0 + x0) * kx, (v1 - uv[:, 1] + y0) * ky]) + PAD - 0.5

    errors = {}
    for k, part in enumerate(result.parts):
        later = [p.outline for p in result.parts[k + 1:]]
        visible = part.outline.difference(unary_union(later)) if later else part.outline
        if visible.area < 4.0:
            continue
        zone = visible.buffer(search_mm)
        (ax, ay), (bx, by) = to_px([zone.bounds[:2], zone.bounds[2:]])
        c0, c1 = max(0, int(min(ax, bx))), min(canvas.shape[1], int(max(ax, bx)) + 2)
        r0, r1 = max(0, int(min(ay, by))), min(canvas.shape[0], int(max(ay, by)) + 2)
        target = np.array([round(255 * c) for c in part.fill_rgb], np.int16)
        roi = canvas[r0:r1, c0:c1].astype(np.int16)
        mask = (np.abs(roi - target).max(axis=2) <= 12).astype(np.uint8)
        mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((5, 5), np.uint8))
        n, lab, stats, cents = cv2.connectedComponentsWithStats(mask)
        zone_px = [(to_px(np.asarray(g.exterior.coords)) - (c0, r0)).astype(np.float32)
                   for g in getattr(zone, "geoms", [zone])]
        inside = [i for i in range(1, n) if stats[i, cv2.CC_STAT_AREA] > 20
                  and any(cv2.pointPolygonTest(z, tuple(cents[i]), False) >= 0
                          for z in zone_px)]
        assert inside, f"{part.name}: its outline is not where the layout has it"
        seen = np.isin(lab, inside).astype(np.uint8)
        contours, _ = cv2.findContours(seen, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
        pts = to_mm(np.concatenate([c.reshape(-1, 2) for c in contours]) + (c0, r0))
        errors[part.name] = float(np.linalg.norm(_shift(pts, visible.boundary, search_mm)))
    return errors


@pytest.fixture(scope="module", params=["ballrun", "causality_switch"])
def made(request, tmp_path_factory):
    name = request.param
    scenario = load_scenario(f"scenarios/{name}.toml")
    _, values = resolve_layout(scenario, "solved", None)
    scene = make_scene(scenario, values, load_parts(scenario))
    result = scene_template(scenario, scene, tmp_path_factory.mktemp(name), paper="a4")
    doc = pdfium.PdfDocument(str(result.pdf))
    pages = [np.asarray(doc[i].render(scale=DPI / 72).to_pil().convert("RGB"))
             for i in range(len(doc))]
    texts = [doc[i].get_textpage().get_text_range() for i in range(len(doc))]
    doc.close()
    return name, result, pages, texts


def test_cut_and_taped_sheets_put_every_part_where_the_layout_has_it(made):
    name, result, pages, texts = made
    assert len(result.sheets) >= 2
    canvas, _ = assemble(result, pages)
    errors = part_errors(result, canvas, 3.0)
    assert len(errors) >= 0.8 * len(result.parts)
    worst = max(errors, key=errors.get)
    print(f"{name}: worst part {worst} off by {errors[worst]:.3f} mm "
          f"({len(errors)} parts, {len(result.sheets)} sheets)")
    assert errors[worst] < TOLERANCE_MM, f"{name}: {worst} off by {errors[worst]:.2f} mm"
    # every seam's letter pairs are printed on both of its sheets
    for s in result.sheets:
        if s.col == 0 and s.row == 0:
            continue
        mine = set(re.findall(r"\b[A-Z]{2}\b", texts[s.page - 1]))
        for nb in result.sheets:
            if (nb.col, nb.row) in ((s.col - 1, s.row), (s.col, s.row - 1)):
                shared = mine & set(re.findall(r"\b[A-Z]{2}\b", texts[nb.page - 1]))
                assert len(shared) >= 2, (s.label, nb.label)


@pytest.mark.parametrize("scale", [0.98, 1.02])
def test_a_misscaled_print_misplaces_parts_and_verify_print_says_so(made, scale, tmp_path):
    name, result, pages, _ = made
    pages = [printed(p, scale) for p in pages]
    canvas, _ = assemble(result, pages)
    errors = part_errors(result, canvas, 25.0)
    worst = max(errors.values())
    print(f"{name} at {scale:.0%}: worst part off by {worst:.2f} mm")
    assert worst > 2 * TOLERANCE_MM  # the assembly is visibly wrong ...
    sheet = result.sheets[-1]
    scan = tmp_path / "scan.png"
    Image.fromarray(pages[sheet.page - 1]).save(scan, dpi=(DPI, DPI))
    check = verify_print(scan)  # ... and the check of any one sheet says why
    assert check.sheet == sheet.label
    assert abs(check.scale_error_percent - 100 * (scale - 1)) < 0.3, check
    assert "reprint" in check.message
