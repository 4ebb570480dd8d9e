"""Reading a scan or photo and finding the template's marks in it.

:func:`load_image` reads an image file as grey levels (with the resolution it records, if
any); :func:`detect_marks` finds the AprilTag 36h11 marks of rgmcad templates with sub-pixel
corners.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from rgmcad.errors import PrintCheckError
from rgmcad.printing.sheets import decode_tag_id

MAX_PIXELS = 80_000_000  # largest image read (under PIL's warning, 89 million)


def load_image(path: Path) -> tuple[np.ndarray, float | None]:
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
