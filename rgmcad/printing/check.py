"""Check the scale of a printed template sheet from a scan or a photo of it.

The sheet's AprilTag marks (see :mod:`rgmcad.printing.sheets` for their ids and positions) tell
which sheet it is and where its marks were meant to be, in millimetres. A picture has no
scale of its own, so the marks' spacing is compared against a reference of known size:

``"dpi"``
    the scan's resolution, when the file records one (PNG pHYs, JPEG density): printed
    millimetres = pixels / dpi * 25.4. Used when the marks fit a similarity (a flat scan)
    and the implied scale is plausible (phones often write 72 dpi into photos).
``"sheet-edges"``
    the paper itself: the picture is rectified with the homography from the marks' corners
    to their planned positions, the sheet's edges are found against the darker background
    around it, and the sheet's measured size is compared with the paper's true size. If the
    print came out at 97 %, the marks are 3 % closer together relative to the paper's edges,
    so the paper measures 1 / 0.97 of its size in the marks' frame.

The paper size is recognised from the marks' layout (their spacing relative to their size).
"""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rgmcad.errors import PrintCheckError
from rgmcad.printing.sheets import PAPERS_MM, decode_tag_id, mark_corners_portrait, slot_label

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TOLERANCE_PERCENT = 0.5
"""Scale errors beyond this (in %) ask for a reprint."""
_PLAUSIBLE = (0.7, 1.3)  # scales a printer could plausibly have applied
_FLAT_SCAN_MM = 0.3  # rms misfit of a similarity that still counts as a flat scan, mm
_BORDER_MM = 40.0  # rectified area beyond the paper on each side, mm
MAX_PIXELS = 80_000_000  # largest image read (under PIL's warning, 89 million)


@dataclass(frozen=True)
class PrintCheck:
    """Outcome of :func:`verify_print`.

    Attributes
    ----------
    path : str
        The image checked.
    sheet : str
        Label of the sheet (``"A1"``...) or ``"map"`` for the first page.
    tag_ids : tuple of int
        Marks found (of the sheet's slot), sorted.
    paper : str
        Paper size recognised from the marks (``""`` if one mark could not tell).
    scale : float
        Printed size / intended size (1.0 = exact).
    scale_error_percent : float
        ``100 * (scale - 1)``.
    method : str
        ``"dpi"`` or ``"sheet-edges"``.
    message : str
        One line for the user.
    scale_xy : (float, float)
        Scale along the paper's short and long sides (sheet-edges), or twice the one scale.
    residual_mm : float
        RMS misfit of the marks' corners to their planned layout, mm on the paper.
    """

    path: str
    sheet: str
    tag_ids: tuple[int, ...]
    paper: str
    scale: float
    scale_error_percent: float
    method: str
    message: str
    scale_xy: tuple[float, float] = (1.0, 1.0)
    residual_mm: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether the scale is within ``TOLERANCE_PERCENT`` of 100 %."""
        return abs(self.scale_error_percent) <= TOLERANCE_PERCENT


# --- reading and detecting ------------------------------------------------------------------------


def _load(path: Path) -> tuple[np.ndarray, float | None]:
    """Grey image (uint8) and its recorded dpi (None if none); refused past MAX_PIXELS."""
    from PIL import Image, ImageOps

    if not path.is_file():  # missing, a folder, a device or a pipe
        raise PrintCheckError(path, "", "cannot read the image: not an existing file (a scan or photo)")
    size = "too large"
    try:
        with (warnings.catch_warnings(action="ignore", category=Image.DecompressionBombWarning),
              Image.open(path) as im):  # opening reads the header (the size), not the pixels
            if (size := f"{im.width} x {im.height} pixels") and im.width * im.height > MAX_PIXELS:
                raise Image.DecompressionBombError(size)
            im.load()
            dpi = im.info.get("dpi")
            im = ImageOps.exif_transpose(im)
            if im.mode in ("RGBA", "LA", "PA") or (im.mode == "P" and "transparency" in im.info):
                im = Image.alpha_composite(Image.new("RGBA", im.size, (255,) * 4), im.convert("RGBA"))
            if im.mode in ("I;16", "I;16B", "I;16L", "I"):
                arr = np.asarray(im, dtype=np.float64)
                grey = (255.0 * arr / max(1.0, float(arr.max()))).astype(np.uint8)
            else:
                grey = np.asarray(im.convert("L"))
    except Exception as exc:  # PIL's size limit (at open), or a decoder's error on a bad file
        big = f"{size}: expected at most {MAX_PIXELS // 10**6} million pixels (A3 at 600 dpi)"
        raise PrintCheckError(path, "", big if isinstance(exc, Image.DecompressionBombError)
                              else f"cannot read the image ({exc})") from None
    try:
        value = float(np.mean([float(v) for v in dpi])) if dpi else None
    except (TypeError, ValueError):
        value = None
    return np.ascontiguousarray(grey), value if value is not None and value > 1.0 else None


def _detector(refine: str):
    import cv2

    dictionary = cv2.aruco.getPredefinedDictionary(cv2.aruco.DICT_APRILTAG_36h11)
    params = cv2.aruco.DetectorParameters()
    if refine == "apriltag":
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    elif refine == "subpix":
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_SUBPIX
        params.cornerRefinementWinSize = 9
    else:
        params.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_NONE
    return cv2.aruco.ArucoDetector(dictionary, params)


def _detect(grey: np.ndarray, refine: str) -> dict[int, np.ndarray]:
    corners, ids, _ = _detector(refine).detectMarkers(grey)
    found = {}
    if ids is not None:
        for c, i in zip(corners, ids.ravel(), strict=True):
            pts = np.asarray(c, float).reshape(4, 2)
            if refine == "apriltag":
                pts = pts - 0.5  # the AprilTag refinement reports corners shifted by +0.5 px
            found.setdefault(int(i), pts)
    return found


_COARSE_PX = 1600  # long side of the copy searched for marks, px


def detect_marks(grey: np.ndarray) -> dict[int, np.ndarray]:
    """Template marks in a grey image.

    Marks are found on a reduced copy, then each is refined (AprilTag corner refinement)
    in a crop of the full image around it: accurate (about 0.1-0.3 px) and fast on large, noisy photos.

    Returns
    -------
    dict
        ``{tag_id: (4, 2) float}`` corners in pixels (pixel centres at integers), in the
        detector's order, for ids that rgmcad templates use.
    """
    import cv2

    f = min(1.0, _COARSE_PX / max(grey.shape))
    coarse = {}
    if f < 1.0:
        small = cv2.resize(grey, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        coarse = {i: (c + 0.5) / f - 0.5 for i, c in _detect(small, "none").items()}
    if not coarse:
        coarse = _detect(grey, "none")
    found: dict[int, np.ndarray] = {}
    h, w = grey.shape
    for i, c in coarse.items():
        try:
            decode_tag_id(i)
        except ValueError:
            continue
        side = float(np.max(np.ptp(c, axis=0)))
        x0, y0 = np.floor(c.min(0) - 0.5 * side).astype(int)
        x1, y1 = np.ceil(c.max(0) + 0.5 * side).astype(int)
        x0, y0, x1, y1 = max(0, x0), max(0, y0), min(w, x1 + 1), min(h, y1 + 1)
        crop = np.ascontiguousarray(grey[y0:y1, x0:x1])
        fine = None
        for refine in ("apriltag", "subpix"):
            got = _detect(crop, refine).get(i)
            if got is not None and np.abs(got + (x0, y0) - c).max() < 0.1 * side + 3:
                fine = got + (x0, y0)
                break
        found[i] = fine if fine is not None else c
    return found


# --- fits -----------------------------------------------------------------------------------------


def _similarity(src: np.ndarray, dst: np.ndarray):
    """Least-squares similarity ``dst ~ s R src + t``; returns ``(s, R, t, rms)``."""
    ms, md = src.mean(0), dst.mean(0)
    a, b = src - ms, dst - md
    u, sv, vt = np.linalg.svd(b.T @ a / len(src))
    d = np.diag([1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt))])
    r = u @ d @ vt
    s = float(np.trace(np.diag(sv) @ d) / ((a**2).sum() / len(src)))
    t = md - s * r @ ms
    res = dst - (s * src @ r.T + t)
    return s, r, t, float(np.sqrt((res**2).sum(1).mean()))


def _homography(src: np.ndarray, dst: np.ndarray):
    """Least-squares homography src -> dst and its rms misfit (dst units)."""
    import cv2

    h, _ = cv2.findHomography(src.astype(np.float64), dst.astype(np.float64), 0)
    if h is None:
        return None, math.inf
    p = cv2.perspectiveTransform(src.reshape(-1, 1, 2).astype(np.float64), h).reshape(-1, 2)
    return h, float(np.sqrt(((p - dst) ** 2).sum(1).mean()))


def _planned(paper: str, marks: dict[int, np.ndarray]) -> np.ndarray:
    layout = mark_corners_portrait(paper)
    return np.concatenate([layout[decode_tag_id(i)[1]] for i in sorted(marks)])


def _pixels(marks: dict[int, np.ndarray]) -> np.ndarray:
    return np.concatenate([marks[i] for i in sorted(marks)])


# --- sheet edges ----------------------------------------------------------------------------------


def _edge_positions(img, valid, k, fixed_lo, fixed_hi, horizontal, inner_mm, outer_mm):
    """Sub-pixel positions of one paper edge along profiles, in rectified mm.

    Profiles run along rows (``horizontal``) or columns of the rectified image ``img``
    (``k`` px per mm, mm origin at pixel ``_BORDER_MM * k``), at ``fixed`` coordinates in
    [fixed_lo, fixed_hi] mm, from ``outer_mm`` (outside the paper) to ``inner_mm`` (inside,
    before any printing). Returns (n, 2) rows ``(fixed_mm, edge_mm)``.
    """
    out = []
    step = max(1, int(round(2.0 * k)))
    band = max(1, int(round(1.0 * k)))
    a = int(round((fixed_lo + _BORDER_MM) * k))
    b = int(round((fixed_hi + _BORDER_MM) * k))
    i0 = int(round((min(outer_mm, inner_mm) + _BORDER_MM) * k))
    i1 = int(round((max(outer_mm, inner_mm) + _BORDER_MM) * k))
    if i0 < 0 or i1 >= (img.shape[1] if horizontal else img.shape[0]):
        return np.empty((0, 2))
    paper_high = inner_mm > outer_mm
    for f in range(a, b, step):
        if horizontal:
            prof = img[f - band:f + band + 1, i0:i1 + 1].mean(0)
            ok = valid[f - band:f + band + 1, i0:i1 + 1].all()
        else:
            prof = img[i0:i1 + 1, f - band:f + band + 1].mean(1)
            ok = valid[i0:i1 + 1, f - band:f + band + 1].all()
        if not ok or prof.size < 8:
            continue
        x = _step_position(prof if paper_high else prof[::-1], k)
        if x is None:
            continue
        coord = i0 + x if paper_high else i1 - x
        out.append((f / k - _BORDER_MM, coord / k - _BORDER_MM))
    return np.asarray(out, float).reshape(-1, 2)


def _step_position(prof: np.ndarray, k: float) -> float | None:
    """Index (sub-pixel) of the dark-to-bright step nearest the bright end of a profile."""
    n = prof.size
    paper = float(np.median(prof[int(0.8 * n):]))
    dark = float(np.percentile(prof, 10))
    if paper - dark < 25.0:
        return None
    mid = (paper + dark) / 2
    below = np.nonzero(prof < mid)[0]
    if below.size == 0:
        return None
    e = int(below[-1])  # last dark sample before the paper
    w = max(2, int(round(1.5 * k)))
    lo = prof[max(0, e - 2 * w):max(1, e - w)]
    hi = prof[min(n - 1, e + w):min(n, e + 2 * w)]
    if lo.size == 0 or hi.size == 0:
        return None
    mid = (float(np.median(lo)) + float(np.median(hi))) / 2
    j0, j1 = max(0, e - w), min(n - 1, e + w)
    seg = prof[j0:j1 + 1]
    cross = np.nonzero((seg[:-1] < mid) & (seg[1:] >= mid))[0]
    if cross.size == 0:
        return None
    c = cross[np.argmin(np.abs(cross + j0 - e))]
    y0, y1 = seg[c], seg[c + 1]
    return j0 + c + (mid - y0) / (y1 - y0)


def _robust_line(points: np.ndarray) -> tuple[float, float] | None:
    """Fit ``x = a + b t`` to (n, 2) rows ``(t, x)`` with outlier rejection."""
    if len(points) < 8:
        return None
    keep = np.ones(len(points), bool)
    for _ in range(4):
        b, a = np.polyfit(points[keep, 0], points[keep, 1], 1)
        res = points[:, 1] - (a + b * points[:, 0])
        mad = np.median(np.abs(res[keep] - np.median(res[keep]))) + 1e-6
        new = np.abs(res) < max(4.0 * 1.4826 * mad, 0.05)
        if new.sum() < 8 or (new == keep).all():
            break
        keep = new
    if keep.sum() < 0.5 * len(points):
        return None
    return float(a), float(b)


def _sheet_edge_scale(grey: np.ndarray, h_mm_to_px: np.ndarray, paper: str):
    """Scale along the paper's width and height from its edges (None where not found)."""
    import cv2

    w_mm, h_mm = PAPERS_MM[paper]
    # rectified resolution: about the picture's own, within [4, 10] px/mm
    centre = np.array([[[w_mm / 2, h_mm / 2], [w_mm / 2 + 1.0, h_mm / 2], [w_mm / 2, h_mm / 2 + 1.0]]])
    c = cv2.perspectiveTransform(centre, h_mm_to_px)[0]
    du, dv = c[1] - c[0], c[2] - c[0]
    native = math.sqrt(abs(du[0] * dv[1] - du[1] * dv[0]))
    k = float(np.clip(native, 4.0, 10.0))
    size = (int(math.ceil((w_mm + 2 * _BORDER_MM) * k)), int(math.ceil((h_mm + 2 * _BORDER_MM) * k)))
    to_rect = np.array([[k, 0, _BORDER_MM * k], [0, k, _BORDER_MM * k], [0, 0, 1.0]])
    m = to_rect @ np.linalg.inv(h_mm_to_px)
    img = cv2.warpPerspective(grey, m, size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0).astype(np.float32)
    valid = cv2.warpPerspective(np.full(grey.shape, 255, np.uint8), m, size,
                                flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                                borderValue=0) > 0
    inner, outer = 8.0, -_BORDER_MM + 2.0
    left = _edge_positions(img, valid, k, 0.25 * h_mm, 0.75 * h_mm, True, inner, outer)
    right = _edge_positions(img, valid, k, 0.25 * h_mm, 0.75 * h_mm, True, w_mm - inner, w_mm - outer)
    top = _edge_positions(img, valid, k, 0.25 * w_mm, 0.75 * w_mm, False, inner, outer)
    bottom = _edge_positions(img, valid, k, 0.25 * w_mm, 0.75 * w_mm, False, h_mm - inner, h_mm - outer)
    lines = [_robust_line(p) for p in (left, right, top, bottom)]
    log.debug("edge profiles: %s", [len(p) for p in (left, right, top, bottom)])
    scales = []
    for (l1, l2), true_mm, mid in ((lines[:2], w_mm, h_mm / 2), (lines[2:], h_mm, w_mm / 2)):
        if l1 is None or l2 is None:
            scales.append(None)
            continue
        slope = (l1[1] + l2[1]) / 2
        gap = (l2[0] + l2[1] * mid) - (l1[0] + l1[1] * mid)
        measured = gap * math.cos(math.atan(slope))
        scales.append(true_mm / measured if measured > 0 else None)
    return scales[0], scales[1]


# --- the check ------------------------------------------------------------------------------------


def _message(scale: float) -> str:
    if abs(scale - 1.0) * 100.0 > TOLERANCE_PERCENT:
        return (f"scale {scale * 100:.1f} %: reprint at actual size "
                "(100 %, no 'fit to page')")
    return f"scale OK ({scale * 100:.1f} %)"


def verify_print(image_path) -> PrintCheck:
    """Measure the scale a template sheet was printed at, from a scan or a photo.

    Parameters
    ----------
    image_path : str or Path
        A scan (with its resolution recorded, e.g. a PNG with pHYs) or a photo of one
        printed sheet, lying flat on a darker background, the whole sheet in view.

    Returns
    -------
    PrintCheck

    Raises
    ------
    PrintCheckError
        The image cannot be read, has no template marks, or its scale cannot be measured.
    """
    path = Path(image_path)
    grey, dpi = _load(path)
    marks = detect_marks(grey)
    if not marks:
        raise PrintCheckError(path, "", "no template marks (AprilTag 36h11) found: scan or "
                              "photograph the whole sheet, flat and in focus")
    slots: dict[int, list[int]] = {}
    for i in marks:
        slots.setdefault(decode_tag_id(i)[0], []).append(i)
    slot = max(slots, key=lambda s: (len(slots[s]), -s))
    if len(slots) > 1:
        log.info("marks of several sheets in %s; checking %s", path, slot_label(slot))
    marks = {i: marks[i] for i in slots[slot]}
    label = slot_label(slot)
    ids = tuple(sorted(marks))
    px = _pixels(marks)

    fits = {}
    for paper in PAPERS_MM:
        src = _planned(paper, marks)
        s, _, _, rms_sim = _similarity(src, px)
        h, rms_h = _homography(src, px) if len(marks) >= 2 else (None, math.inf)
        fits[paper] = (s, rms_sim / s, h, rms_h / s)
    one_mark = len(marks) == 1

    # (a) a flat scan with a recorded resolution
    if dpi is not None:
        paper = "" if one_mark else min(fits, key=lambda p: fits[p][1])
        s, rms_mm = fits[paper or "a4"][:2]
        scale = s * 25.4 / dpi
        if _PLAUSIBLE[0] < scale < _PLAUSIBLE[1] and rms_mm < _FLAT_SCAN_MM:
            return PrintCheck(str(path), label, ids, paper, scale, 100.0 * (scale - 1.0),
                              "dpi", _message(scale), (scale, scale), rms_mm)
        log.info("recorded %.0f dpi gives scale %.3f (misfit %.2f mm): using sheet edges",
                 dpi, scale, rms_mm)

    # (b) the paper's edges
    if len(marks) < 2:
        raise PrintCheckError(path, "", f"only one mark found ({ids[0]}): photograph the whole "
                              "sheet on a darker background, or scan it (recording its dpi)")
    ranked = sorted(fits, key=lambda p: fits[p][3])
    best, second = fits[ranked[0]][3], fits[ranked[1]][3]
    clear = len(marks) >= 3 and best < 0.5 * second
    candidates = ranked[:1] if clear else ranked
    results = []
    for paper in candidates:
        sw, sh = _sheet_edge_scale(grey, fits[paper][2], paper)
        found = [v for v in (sw, sh) if v is not None]
        if not found:
            continue
        spread = abs(sw - sh) if len(found) == 2 else 0.05
        results.append((spread + (0.0 if paper == ranked[0] else 1e-4), paper, sw, sh))
    if not results:
        raise PrintCheckError(path, "", "cannot find the sheet's edges: photograph the whole "
                              "sheet flat on a darker background, or scan it (recording its dpi)")
    _, paper, sw, sh = min(results)
    found = [v for v in (sw, sh) if v is not None]
    scale = float(np.mean(found))
    message = _message(scale)
    if len(found) == 2 and abs(sw - sh) > 0.01:
        message += (f" (width {sw * 100:.1f} %, height {sh * 100:.1f} %: is the paper "
                    f"{paper}, and flat?)")
    sw = sw if sw is not None else scale
    sh = sh if sh is not None else scale
    return PrintCheck(str(path), label, ids, paper, scale, 100.0 * (scale - 1.0),
                      "sheet-edges", message, (sw, sh), fits[paper][3])
