"""Check the scale of a printed template sheet from a scan or a photo of it.

The sheet's AprilTag marks (see :mod:`rgmcad.printing.sheets` for their ids and positions)
tell which sheet it is and where its marks were meant to be, in millimetres; the label is
reported whenever the marks are read. A picture has no scale of its own, and the marks
scale with the print, so the printed scale needs a reference of known size:

``"dpi"``
    a scan's resolution, when the file records one (PNG pHYs, JPEG density): printed
    millimetres = pixels / dpi * 25.4. Used when the marks fit a similarity (a flat scan)
    and the implied scale is plausible (phones often write 72 dpi into photos).
``"sheet-edges"``
    the paper itself (:mod:`rgmcad.printing.edges`): the marks fix the sheet's position and
    perspective, and two opposite edges of the paper, seen against a few millimetres of a
    darker table, fix the scale along that axis.

A sheet that is not flat (a curled edge or corner) makes the paper look smaller and the
print larger than it is; it is detected before any scale is reported: the marks' corners do
not fit one plane (their homography misfits), an edge is not straight, or the widths and
heights disagree. The check then asks to flatten the sheet and retake the photo.

What a photo needs: the whole sheet, or at least two opposite edges of it with a strip of
table (3 mm or more, darker than the paper) beyond them; at least two of the four marks
(three or four are better); the sheet flat (weighted at the corners); in focus, at any
angle up to about 35 degrees from straight above; 3 megapixels or more.
"""

from __future__ import annotations

import enum
import logging
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rgmcad.errors import PrintCheckError
from rgmcad.printing.edges import measure_edges
from rgmcad.printing.marks import detect_marks, load_image
from rgmcad.printing.sheets import PAPERS_MM, decode_tag_id, mark_corners_portrait, slot_label

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

TOLERANCE_PERCENT = 0.5
"""Scale errors beyond this (in %) ask for a reprint."""
FLAT_MARKS_MM = 0.15
"""Misfit (mm on the paper) of a mark's corner to the plane of all marks beyond which the
sheet is not flat (or one photo pixel, if that is more)."""
FLAT_EDGE_MM = 0.35
"""Bow of an edge (mm) beyond which the sheet is not flat."""
FLAT_AXES = 0.004
"""Disagreement of the width's and height's scales beyond which the sheet is not flat."""
_PLAUSIBLE = (0.7, 1.3)  # scales a printer could plausibly have applied
_FLAT_SCAN_MM = 0.3  # rms misfit of a similarity that still counts as a flat scan, mm


class Verdict(enum.Enum):
    """Outcome of a print check."""

    OK = "ok"
    """Scale within ``TOLERANCE_PERCENT`` of 100 %."""
    REPRINT = "reprint"
    """Scale measured, off by more than ``TOLERANCE_PERCENT``."""
    NOT_FLAT = "not-flat"
    """The sheet is not flat in the photo: no scale reported; flatten it and retake."""
    NO_SCALE = "no-scale"
    """Sheet recognised, but nothing in the picture gives the scale."""


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
    verdict : Verdict
    scale : float or None
        Printed size / intended size (1.0 = exact); None unless measured.
    scale_error_percent : float or None
        ``100 * (scale - 1)``.
    method : str
        ``"dpi"``, ``"sheet-edges"``, or ``"marks"`` (sheet recognised, no scale).
    message : str
        One line for the user.
    scale_xy : (float or None, float or None)
        Scale along the paper's short and long sides (sheet-edges), or twice the one scale.
    residual_mm : float
        RMS misfit of the marks' corners to their planned layout (one plane), mm.
    bow_mm : float
        Largest bow of a paper edge, mm (sheet-edges).
    """

    path: str
    sheet: str
    tag_ids: tuple[int, ...]
    paper: str
    verdict: Verdict
    scale: float | None
    scale_error_percent: float | None
    method: str
    message: str
    scale_xy: tuple = (None, None)
    residual_mm: float = 0.0
    bow_mm: float = 0.0

    @property
    def ok(self) -> bool:
        """Whether the scale was measured and is within ``TOLERANCE_PERCENT`` of 100 %."""
        return self.verdict is Verdict.OK


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


def _message(scale: float) -> tuple[Verdict, str]:
    if abs(scale - 1.0) * 100.0 > TOLERANCE_PERCENT:
        return Verdict.REPRINT, (f"scale {scale * 100:.1f} %: reprint at actual size "
                                 "(100 %, no 'fit to page')")
    return Verdict.OK, f"scale OK ({scale * 100:.1f} %)"


def _measured(path, label, ids, paper, scale, method, xy, residual, bow=0.0) -> PrintCheck:
    verdict, message = _message(scale)
    return PrintCheck(str(path), label, ids, paper, verdict, scale, 100.0 * (scale - 1.0),
                      method, message, xy, residual, bow)


def _marks_residual_mm(px: np.ndarray, mm: np.ndarray) -> tuple[float, float, float]:
    """Misfit of the marks' corners to one plane (the homography photo -> paper): rms and
    largest, mm on the paper, and the size of one photo pixel there, mm."""
    import cv2

    h, _ = cv2.findHomography(px.astype(np.float64), mm.astype(np.float64), 0)
    if h is None:
        return math.inf, math.inf, 0.0
    p = cv2.perspectiveTransform(px.reshape(-1, 1, 2).astype(np.float64), h).reshape(-1, 2)
    r = np.linalg.norm(p - mm, axis=1)
    pixel = float(np.sqrt(np.ptp(mm[:, 0]) * np.ptp(mm[:, 1]) /
                          max(1e-9, np.ptp(px[:, 0]) * np.ptp(px[:, 1]))))
    return float(np.sqrt((r**2).mean())), float(r.max()), pixel


def _from_edges(path, grey, label, ids, marks, fits) -> PrintCheck:
    """The check by the paper's edges (two marks or more)."""
    px = _pixels(marks)
    ranked = sorted(fits, key=lambda p: fits[p][3])
    clear = len(marks) >= 3 and fits[ranked[0]][3] < 0.5 * fits[ranked[1]][3]
    paper = ranked[0]
    residual, worst, pixel = (_marks_residual_mm(px, _planned(paper, marks)) if len(marks) >= 3
                              else (0.0, 0.0, 0.0))
    bent = worst > max(FLAT_MARKS_MM, pixel)
    readings = {}
    for p in ranked[:1] if clear else ranked:
        readings[p] = measure_edges(grey, fits[p][2], p)
    if not clear:  # the paper whose edges agree best
        def spread(p):
            r = readings[p]
            both = r.scale_w is not None and r.scale_h is not None
            return (abs(r.scale_w - r.scale_h) if both else 1.0) + (0 if p == paper else 1e-4)
        paper = min(readings, key=spread)
    r = readings[paper]
    found = [v for v in (r.scale_w, r.scale_h) if v is not None]
    common = (str(path), label, ids, paper)
    why = []
    if bent:
        why.append(f"a mark's corner is {worst:.2f} mm off the plane of the others")
    if r.bow_mm > FLAT_EDGE_MM:
        why.append(f"an edge bows by {r.bow_mm:.1f} mm")
    if len(found) == 2 and abs(r.scale_w - r.scale_h) > FLAT_AXES:
        why.append(f"width and height read {r.scale_w * 100:.1f} % and "
                   f"{r.scale_h * 100:.1f} %")
    if why:
        return PrintCheck(*common, Verdict.NOT_FLAT, None, None,
                          "sheet-edges", f"sheet {label} is not flat ({'; '.join(why)}): "
                          "flatten the sheet and retake the photo",
                          (r.scale_w, r.scale_h), residual, r.bow_mm)
    if not found:
        return PrintCheck(*common, Verdict.NO_SCALE, None, None, "marks",
                          f"sheet {label} recognised, but no two opposite edges of the paper "
                          "were found against the table: retake with a strip of darker table "
                          "beyond two opposite edges, or scan the sheet (recording its dpi)",
                          (None, None), residual)
    return _measured(*common, float(np.mean(found)), "sheet-edges", (r.scale_w, r.scale_h),
                     residual, r.bow_mm)


def verify_print(image_path) -> PrintCheck:
    """Measure the scale a template sheet was printed at, from a scan or a photo.

    Parameters
    ----------
    image_path : str or Path
        A scan (with its resolution recorded, e.g. a PNG with pHYs) or a photo of one
        printed sheet (see the module docstring for what a photo needs).

    Returns
    -------
    PrintCheck
        With the sheet's label whenever its marks were read; ``verdict`` says whether a
        scale was measured (:class:`Verdict`).

    Raises
    ------
    PrintCheckError
        The image cannot be read, or has no template marks.
    """
    import cv2

    path = Path(image_path)
    grey, dpi = load_image(path)
    try:
        return _check(path, grey, dpi)
    except (cv2.error, np.linalg.LinAlgError) as exc:  # an image no guard foresaw: one line
        why = " ".join(str(exc).split())[:200]
        raise PrintCheckError(path, "", f"cannot analyse the image ({type(exc).__name__}: "
                              f"{why}); scan or photograph the whole sheet") from None


def _check(path: Path, grey: np.ndarray, dpi: float | None) -> PrintCheck:
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

    # (a) a flat scan with a recorded resolution
    if dpi is not None:
        paper = "" if len(marks) == 1 else min(fits, key=lambda p: fits[p][1])
        s, rms_mm = fits[paper or "a4"][:2]
        scale = s * 25.4 / dpi
        if _PLAUSIBLE[0] < scale < _PLAUSIBLE[1] and rms_mm < _FLAT_SCAN_MM:
            return _measured(path, label, ids, paper, scale, "dpi", (scale, scale), rms_mm)
        log.info("recorded %.0f dpi gives scale %.3f (misfit %.2f mm): using sheet edges",
                 dpi, scale, rms_mm)

    # (b) the paper's edges
    if len(marks) < 2:
        return PrintCheck(str(path), label, ids, "", Verdict.NO_SCALE, None, None, "marks",
                          f"sheet {label} recognised from one mark ({ids[0]}): photograph "
                          "the whole sheet (two marks or more), or scan it (recording its dpi)")
    return _from_edges(path, grey, label, ids, marks, fits)
