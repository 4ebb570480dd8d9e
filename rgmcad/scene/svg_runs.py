"""Domino runs drawn in a vector editor: the path of an SVG file, read as a polyline in metres.

A run's ``path = { kind = "svg", file = "curve.svg", spacing = 0.015 }`` places its dominoes
along the first ``<path>`` of the file (or the one whose ``id`` is ``element``), with the
spacing rule of a polyline path (:func:`rgmcad.scene.dominoes.polyline`). The drawing's
coordinates are its millimetres (the file must give its width and height in a physical unit,
as Inkscape and Illustrator do), with the drawing's y axis turned up: x right, y up, in the
run's own frame, whose pose (and free ranges) the scenario gives like any other run's.
Transforms of groups and elements apply; curves and arcs become chords of at most
:data:`CHORD` long.
"""

from __future__ import annotations

import functools
import io
import math
import re
from pathlib import Path

import numpy as np

from rgmcad.scene import dominoes
from rgmcad.scene.loader_checks import FileRefused, read_limited, size_text

CHORD = 5e-4
"""Longest chord (m) standing for a piece of curve."""
MAX_SVG_BYTES = 2 * 2**20
MAX_POINTS = 200_000
"""Points of the followed path (a 100 m curve at :data:`CHORD`)."""
PX_TO_M = 0.0254 / 96
"""svgelements gives lengths in CSS pixels (96 per inch)."""
_PHYSICAL = re.compile(r"\s*[0-9.eE+-]+\s*(mm|cm|in|pt|pc|q)\s*$", re.IGNORECASE)


def read_points(file: str | Path, element: str | None = None) -> np.ndarray:
    """(k, 2) points (m) of the SVG path, in the drawing's frame with y up. ValueError (one
    line) if the file cannot be read (its size is checked before it is read) or holds no
    such path."""
    path = Path(file)
    try:
        raw = read_limited(path, MAX_SVG_BYTES)
    except FileNotFoundError:
        raise ValueError(f"no SVG file {str(path)!r}") from None
    except FileRefused as exc:
        why = (f"{exc}; a drawing may hold at most {size_text(MAX_SVG_BYTES)}"
               if str(exc).startswith("the file holds") else f"{exc}; expected an SVG file")
        raise ValueError(f"{path.name}: {why}") from None
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path.name}: cannot read the file "
                         f"({getattr(exc, 'strerror', None) or exc})") from None
    return _points(raw, element, path.name).copy()


@functools.lru_cache(maxsize=4)
def _points(raw: bytes, element: str | None, name: str) -> np.ndarray:
    """:func:`read_points` of a file's bytes, kept: a run's drawing is counted, then placed."""
    import svgelements as se

    try:
        doc = se.SVG.parse(io.BytesIO(raw))
    except Exception as exc:  # noqa: BLE001 - any parser failure is the file's fault
        raise ValueError(f"{name}: not an SVG file ({type(exc).__name__})") from None
    for side in ("width", "height"):
        if not _PHYSICAL.match(str(doc.values.get(side, ""))):
            raise ValueError(f"{name}: the drawing's {side} has no physical unit "
                             "(mm, cm, in, pt); save it with its size in millimetres")
    paths = [e for e in doc.elements() if isinstance(e, se.Path) and len(e) > 0]
    if element is not None:
        paths = [e for e in paths if e.id == element]
    if not paths:
        which = f"no <path> with id {element!r}" if element else "no <path>"
        raise ValueError(f"{name}: {which}")
    points: list[tuple[float, float]] = []
    pieces = 0
    for seg in paths[0].segments():
        if isinstance(seg, se.Move):
            pieces += 1
            if pieces > 1:
                raise ValueError(f"{name}: the path lifts the pen (several pieces); "
                                 "draw one continuous line")
            points.append(_xy(seg.end))
            continue
        n = 1 if isinstance(seg, se.Line | se.Close) else max(
            2, math.ceil(seg.length() * PX_TO_M / CHORD))
        if not len(points) + n <= MAX_POINTS:  # also refuses a length that is not a number
            raise ValueError(f"{name}: the path is too long to follow (more than "
                             f"{MAX_POINTS * CHORD:g} m of curves)")
        points.extend(_xy(seg.point(t)) for t in np.linspace(0, 1, n + 1)[1:])
    pts = np.asarray(points, float)
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9])
    pts = pts[keep]
    if len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise ValueError(f"{name}: the path has no length")
    return pts


def _xy(point) -> tuple[float, float]:
    return float(point.x) * PX_TO_M, -float(point.y) * PX_TO_M


def svg(file: str, element: str | None = None, count: int | None = None,
        spacing: float | None = None) -> np.ndarray:
    """(n, 3) dominoes (x, y, heading in degrees) along an SVG path: see the module."""
    return dominoes.polyline(read_points(file, element), count=count, spacing=spacing)


def svg_count(file: str, element: str | None = None, count: int | None = None,
              spacing: float | None = None) -> int:
    """How many dominoes :func:`svg` places, computed without placing them."""
    return dominoes.polyline_count(read_points(file, element), count=count, spacing=spacing)
