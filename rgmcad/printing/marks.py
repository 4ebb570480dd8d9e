"""Reading a scan or photo and finding the template's marks in it.

:func:`load_image` reads an image file as grey levels (with the resolution it records, if
any); :func:`detect_marks` finds the AprilTag 36h11 marks of rgmcad templates with sub-pixel
corners.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np

from rgmcad.errors import PrintCheckError
from rgmcad.printing.sheets import decode_tag_id

MAX_PIXELS = 80_000_000  # largest image read (under PIL's warning, 89 million)
MIN_SIDE = 32
"""Fewest pixels across an image, either way: a template mark (8 x 8 cells inside a white
border) needs about 3 pixels a cell to be read, and a sheet holds it with room around."""


class _Refused(Exception):
    """An image of a size this check does not read (the message says which)."""


def load_image(path: Path) -> tuple[np.ndarray, float | None]:
    """Grey image (uint8) and its recorded dpi (None if none, or not a plausible number);
    refused (:class:`PrintCheckError`) past :data:`MAX_PIXELS`, under :data:`MIN_SIDE`
    pixels either way, or when it is not an image that can be decoded."""
    from PIL import Image, ImageOps

    if not path.is_file():  # missing, a folder, a device or a pipe
        raise PrintCheckError(path, "", "cannot read the image: not an existing file (a scan or photo)")
    try:
        with (warnings.catch_warnings(action="ignore", category=Image.DecompressionBombWarning),
              Image.open(path) as im):  # opening reads the header (the size), not the pixels
            _check_size(im.width, im.height)
            im.load()
            dpi = im.info.get("dpi")
            im = ImageOps.exif_transpose(im)
            _check_size(im.width, im.height)
            grey = _grey(im)
    except _Refused as exc:
        raise PrintCheckError(path, "", str(exc)) from None
    except Image.DecompressionBombError:  # PIL's own limit, at open: past twice its 89 million
        raise PrintCheckError(path, "", f"too large: expected at most {MAX_PIXELS // 10**6} "
                              "million pixels (A3 at 600 dpi)") from None
    except Exception as exc:  # a decoder's error on a bad file
        raise PrintCheckError(path, "", f"cannot read the image ({type(exc).__name__}: "
                              f"{str(exc)[:200]}); expected a PNG, JPEG or TIFF scan or "
                              "photo") from None
    try:
        value = float(np.mean([float(v) for v in dpi])) if dpi else None
    except (TypeError, ValueError):
        value = None
    plausible = value is not None and math.isfinite(value) and 1.0 < value < 100_000.0
    return np.ascontiguousarray(grey), value if plausible else None


def _check_size(width: int, height: int) -> None:
    size = f"{width} x {height} pixels"
    if width * height > MAX_PIXELS:
        raise _Refused(f"{size}: expected at most {MAX_PIXELS // 10**6} million pixels (A3 at "
                       "600 dpi)")
    if min(width, height) < MIN_SIDE:
        raise _Refused(f"{size}: too small, no template marks fit in it; expected at least "
                       f"{MIN_SIDE} pixels each way (a scan or photo of a whole sheet)")


def _grey(im) -> np.ndarray:
    """The image as grey levels, uint8 (2-D): transparency over white, 16-bit, integer and
    float images stretched from their darkest to their lightest value."""
    from PIL import Image

    if im.mode in ("RGBA", "LA", "PA", "RGBa", "La") or (im.mode == "P" and "transparency" in im.info):
        im = Image.alpha_composite(Image.new("RGBA", im.size, (255,) * 4), im.convert("RGBA"))
    if im.mode.startswith(("I", "F")):
        arr = np.nan_to_num(np.asarray(im, dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
        low, high = (float(arr.min()), float(arr.max())) if arr.size else (0.0, 0.0)
        if high <= 255.0 and low >= 0.0 and im.mode.startswith("F"):
            low, high = 0.0, 255.0  # a float image of 8-bit levels: as it is
        grey = (255.0 * (arr - low) / max(high - low, 1e-12)).round().clip(0, 255).astype(np.uint8)
    else:
        grey = np.asarray(im.convert("L"))
    if grey.ndim != 2 or grey.dtype != np.uint8:
        raise ValueError(f"mode {im.mode} gave {grey.dtype} pixels of shape {grey.shape}")
    return grey


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
    if grey.size == 0:  # a crop at the image's edge
        return {}
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

    if grey.ndim != 2 or min(grey.shape) < MIN_SIDE:  # no mark fits
        return {}
    grey = np.ascontiguousarray(grey, dtype=np.uint8)
    f = min(1.0, _COARSE_PX / max(grey.shape))
    coarse = {}
    if f < 1.0 and min(grey.shape) * f >= MIN_SIDE:  # a long thin strip: searched whole
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
