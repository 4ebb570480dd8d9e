"""The paper's edges in a photo, measured in the frame the sheet's marks define.

The marks fix a homography from the planned sheet (mm) to the photo; the photo is rectified
with it, and each edge of the paper is found along short profiles that start inside the
paper's blank margin and run outwards until the paper gives way to the (darker) table or
the photo ends. A few millimetres of table beyond an edge are enough, and an edge cut off
by the photo's border is simply missing. If the print came out at 97 %, the marks are 3 %
closer together relative to the paper, so the paper measures 1 / 0.97 of its true size in
the marks' frame: two opposite edges give the scale along that axis.

The profiles run along the whole edge, so an edge that is not straight (a curled or lifted
part of the sheet) shows as a bow of the edge points about their line.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rgmcad.printing.sheets import PAPERS_MM

BORDER_MM = 50.0
"""Rectified area beyond the paper on each side, mm (a print down to about 75 %)."""
INNER_MM = 7.0
"""Where profiles start: inside the paper's blank margin (10 mm), mm from its edge."""
MIN_STEP = 25.0
"""Smallest drop in grey level from paper to table that counts as an edge."""
END_MM = 4.0
"""Profiles stop this far from the paper's corners, mm."""


@dataclass(frozen=True)
class EdgeReading:
    """What the paper's edges say, in the marks' frame.

    Attributes
    ----------
    scale_w, scale_h : float or None
        Printed size / true size along the paper's width and height (portrait frame), from
        two opposite edges; None where one of them was not found.
    bow_mm : float
        Largest deviation of an edge's points from its straight line (median over 15 mm
        stretches), mm; 0 when no edge was found.
    sides : tuple of str
        Edges found: some of ``"left"``, ``"right"``, ``"top"``, ``"bottom"``.
    """

    scale_w: float | None
    scale_h: float | None
    bow_mm: float
    sides: tuple[str, ...]


def _rectify(grey, h_mm_to_px, paper):
    import cv2

    w_mm, h_mm = PAPERS_MM[paper]
    centre = np.array([[[w_mm / 2, h_mm / 2], [w_mm / 2 + 1.0, h_mm / 2], [w_mm / 2, h_mm / 2 + 1.0]]])
    c = cv2.perspectiveTransform(centre, h_mm_to_px)[0]
    du, dv = c[1] - c[0], c[2] - c[0]
    k = float(np.clip(math.sqrt(abs(du[0] * dv[1] - du[1] * dv[0])), 4.0, 10.0))
    size = (int(math.ceil((w_mm + 2 * BORDER_MM) * k)), int(math.ceil((h_mm + 2 * BORDER_MM) * k)))
    to_rect = np.array([[k, 0, BORDER_MM * k], [0, k, BORDER_MM * k], [0, 0, 1.0]])
    m = to_rect @ np.linalg.inv(h_mm_to_px)
    img = cv2.warpPerspective(grey, m, size, flags=cv2.INTER_LINEAR,
                              borderMode=cv2.BORDER_CONSTANT, borderValue=0).astype(np.float32)
    valid = cv2.warpPerspective(np.full(grey.shape, 255, np.uint8), m, size,
                                flags=cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT,
                                borderValue=0) > 0
    valid = cv2.erode(valid.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    return img, valid, k


def _profiles(img, valid, k, side, paper):
    """``(along_mm, samples)`` per profile of one side, each running outwards from
    ``INNER_MM`` inside the paper, cut where the photo ends."""
    w_mm, h_mm = PAPERS_MM[paper]
    length = h_mm if side in ("left", "right") else w_mm
    band = max(1, int(round(0.75 * k)))
    off = BORDER_MM * k
    out = []
    for t in np.arange(END_MM, length - END_MM, 2.0):
        f = int(round(t * k + off))
        if side in ("left", "top"):
            start, stop, direction = int(round(INNER_MM * k + off)), 0, -1
        else:
            far = (w_mm if side == "right" else h_mm) - INNER_MM
            start = int(round(far * k + off))
            stop, direction = (img.shape[1] if side == "right" else img.shape[0]) - 1, 1
        idx = np.arange(start, stop, direction)
        if side in ("left", "right"):
            prof = img[f - band:f + band + 1, idx].mean(0)
            ok = valid[f - band:f + band + 1, idx].all(0)
        else:
            prof = img[idx, f - band:f + band + 1].mean(1)
            ok = valid[idx, f - band:f + band + 1].all(1)
        n = int(np.argmin(ok)) if not ok.all() else len(ok)
        out.append((t, prof[:n], start))
    return out, off


def _edge_in(prof: np.ndarray, k: float) -> tuple[float, float] | None:
    """Sub-pixel index (from the inner end) where the bright paper gives way to the table,
    and the step's height in grey levels."""
    w = max(2, int(round(1.0 * k)))
    if prof.size < int(INNER_MM * k) + 2 * w:
        return None
    paper = float(np.median(prof[:int(2.5 * k)]))
    smooth = np.convolve(prof, np.ones(3) / 3, mode="same")
    below = np.nonzero(smooth[w:] < paper - MIN_STEP)[0]
    if below.size == 0:
        return None
    i = int(below[0]) + w
    dark_part = prof[i + w:i + 3 * w]
    if dark_part.size < w:
        return None
    dark = float(np.median(dark_part))
    if paper - dark < MIN_STEP:
        return None
    mid = (paper + dark) / 2
    j0 = max(1, i - 2 * w)
    seg = prof[j0:i + w + 1]
    cross = np.nonzero((seg[:-1] >= mid) & (seg[1:] < mid))[0]
    if cross.size == 0:
        return None
    c = int(cross[-1])
    y0, y1 = seg[c], seg[c + 1]
    return j0 + c + (y0 - mid) / (y0 - y1), paper - dark


def _robust_line(points: np.ndarray):
    """``(a, b, keep)``: ``x = a + b t`` fitted to (n, 2) rows ``(t, x)``, outliers dropped."""
    if len(points) < 8:
        return None
    keep = np.ones(len(points), bool)
    for _ in range(5):
        b, a = np.polyfit(points[keep, 0], points[keep, 1], 1)
        res = points[:, 1] - (a + b * points[:, 0])
        mad = np.median(np.abs(res[keep] - np.median(res[keep]))) + 1e-6
        new = np.abs(res) < max(5.0 * 1.4826 * mad, 0.08)
        if new.sum() < 8 or (new == keep).all():
            break
        keep = new
    if keep.sum() < 0.6 * len(points):
        return None
    return float(a), float(b), keep


def _bow(points: np.ndarray, line) -> float:
    """Largest |median residual| over 15 mm stretches of an edge, mm: the points within
    3 mm of its line (a lifted corner pulls them that far at most; a finger further)."""
    a, b, _ = line
    res = points[:, 1] - (a + b * points[:, 0])
    near = np.abs(res) < 3.0
    t, res = points[near, 0], res[near]
    worst = 0.0
    for lo in np.arange(t.min(), t.max(), 15.0):
        sel = (t >= lo) & (t < lo + 15.0)
        if sel.sum() >= 4:
            worst = max(worst, abs(float(np.median(res[sel]))))
    return worst


def measure_edges(grey: np.ndarray, h_mm_to_px: np.ndarray, paper: str) -> EdgeReading:
    """The paper's edges in ``grey``, given the homography from the sheet's planned mm
    (portrait frame of ``paper``) to photo pixels."""
    img, valid, k = _rectify(grey, h_mm_to_px, paper)
    w_mm, h_mm = PAPERS_MM[paper]
    lines, found = {}, []
    worst = 0.0
    for side in ("left", "right", "top", "bottom"):
        profiles, off = _profiles(img, valid, k, side, paper)
        pts, steps = [], []
        for t, prof, start in profiles:
            got = _edge_in(prof, k)
            if got is None:
                continue
            sign = -1.0 if side in ("left", "top") else 1.0
            pts.append((t, (start + sign * got[0] - off) / k))
            steps.append(got[1])
        pts = np.asarray(pts, float).reshape(-1, 2)
        if len(pts):  # a weaker step is something over the paper (a finger), not the table
            pts = pts[np.asarray(steps) >= 0.6 * np.median(steps)]
        length = h_mm if side in ("left", "right") else w_mm
        if len(pts) < 0.3 * (length - 2 * END_MM) / 2.0:
            continue
        line = _robust_line(pts)
        if line is None:
            continue
        lines[side] = line
        found.append(side)
        worst = max(worst, _bow(pts, line))
    scales = []
    for (s1, s2), true_mm, mid in ((("left", "right"), w_mm, h_mm / 2),
                                   (("top", "bottom"), h_mm, w_mm / 2)):
        if s1 not in lines or s2 not in lines:
            scales.append(None)
            continue
        l1, l2 = lines[s1], lines[s2]
        slope = (l1[1] + l2[1]) / 2
        gap = (l2[0] + l2[1] * mid) - (l1[0] + l1[1] * mid)
        measured = gap * math.cos(math.atan(slope))
        scales.append(true_mm / measured if measured > 0 else None)
    return EdgeReading(scales[0], scales[1], worst, tuple(found))
