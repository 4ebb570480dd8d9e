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
import math
import re
import warnings
from pathlib import Path

import numpy as np

from rgmcad.scene import dominoes
from rgmcad.scene.loader_checks import FileRefused, read_limited, size_text
from rgmcad.scene.schema import MAX_SVG_BYTES, MAX_SVG_LENGTH, MAX_SVG_REACH
from rgmcad.scene.svg_files import geometry_of

CHORD = 5e-4
"""Longest chord (m) standing for a piece of curve."""
PX_TO_M = 0.0254 / 96
"""svgelements gives lengths in CSS pixels (96 per inch)."""
STRAIGHT = 1e9
"""Radius (m) past which an arc is drawn as its chord: a path of at most MAX_SVG_LENGTH
(100 m) strays from such an arc by at most 100**2 / (8 * 1e9) m, about a micrometre, where
the arc's own centre, that far off, would cost its points their precision."""
_SAMPLES = 16
"""Pieces a curve is first cut into, to measure its length."""
_PHYSICAL = re.compile(r"\s*([0-9.eE+-]+)\s*(mm|cm|in|pt|pc|q)\s*$", re.IGNORECASE)
_UNIT_M = {"mm": 1e-3, "cm": 1e-2, "in": 0.0254, "pt": 0.0254 / 72, "pc": 0.0254 / 6,
           "q": 2.5e-4}


def _float(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def read_points(file: str | Path, element: str | None = None) -> np.ndarray:
    """(k, 2) points (m) of the SVG path, in the drawing's frame with y up. ValueError (one
    line) if the file cannot be read, passes a limit of :mod:`rgmcad.scene.schema` (its size
    is checked before it is read, and its contents before they are parsed:
    :mod:`rgmcad.scene.svg_files`) or holds no such path."""
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
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")  # a drawing's numbers are checked here, not warned of
        return _follow(_path_of(geometry_of(raw, name), element, name), name)


def _path_of(geometry: bytes, element: str | None, name: str):
    """The svgelements Path to follow in the checked ``geometry`` of a drawing."""
    import io

    import svgelements as se

    try:
        doc = se.SVG.parse(io.BytesIO(geometry))
        paths = [e for e in doc.elements() if isinstance(e, se.Path) and len(e) > 0]
    except Exception as exc:  # noqa: BLE001 - any parser failure is the file's fault
        raise ValueError(f"{name}: not an SVG file ({type(exc).__name__})") from None
    for side in ("width", "height"):
        size = _PHYSICAL.match(str(doc.values.get(side, "")))
        if not size:
            raise ValueError(f"{name}: the drawing's {side} has no physical unit "
                             "(mm, cm, in, pt); save it with its size in millimetres")
        metres = _float(size[1]) * _UNIT_M[size[2].lower()]
        if not 0 < metres <= MAX_SVG_REACH:  # not a number, or one the parser gives up on
            raise ValueError(f"{name}: the drawing's {side} is {size[1]} {size[2]}; "
                             f"allowed: more than 0, at most {MAX_SVG_REACH:,g} m")
    if element is not None:
        paths = [e for e in paths if e.id == element]
    if not paths:
        which = f"no <path> with id {element!r}" if element else "no <path>"
        raise ValueError(f"{name}: {which}")
    return paths[0]


def _follow(drawn, name: str) -> np.ndarray:
    """(k, 2) points (m, y up) along the svgelements path ``drawn``: its numbers checked
    (finite, within MAX_SVG_REACH of the origin), its length bounded (MAX_SVG_LENGTH) before
    any curve is cut into chords."""
    import svgelements as se

    segments = list(drawn.segments())
    if sum(isinstance(seg, se.Move) for seg in segments) > 1:
        raise ValueError(f"{name}: the path lifts the pen (several pieces); "
                         "draw one continuous line")
    corners, arcs = [], []  # every point that bounds a segment; (rx, ry, sweep) of each arc
    for seg in segments:
        corners += [p for p in (seg.start, seg.end, getattr(seg, "control", None),
                                getattr(seg, "control1", None), getattr(seg, "control2", None))
                    if p is not None]
        if isinstance(seg, se.Arc):
            arcs.append((seg.rx * PX_TO_M, seg.ry * PX_TO_M, seg.sweep))
    xy = np.array([_xy(p) for p in corners], float).reshape(-1, 2)
    if not np.all(np.isfinite(xy)) or not np.all(np.isfinite(np.array(arcs, float))):
        raise ValueError(f"{name}: a coordinate of the path is not a finite number "
                         "(too large to be one, or not a number)")
    ends = np.array([[_xy(seg.start), _xy(seg.end)] for seg in segments
                     if not isinstance(seg, se.Move)], float).reshape(-1, 2, 2)
    least = float(np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1).sum()) + sum(
        min(rx, ry) * abs(sweep) for rx, ry, sweep in arcs if max(rx, ry) <= STRAIGHT)
    if math.isfinite(least):  # else points so far apart that their distance overflows
        _not_too_long(least, name, at_least=True)
    _within_reach(xy, name, "a point or control point of the path")
    pieces, length = [np.array([_xy(segments[0].end)])], 0.0
    for seg in segments[1:]:
        straight = isinstance(seg, se.Linear | se.Move) or (
            isinstance(seg, se.Arc) and max(seg.rx, seg.ry) * PX_TO_M > STRAIGHT)
        if straight:
            piece = np.array([_xy(seg.end)])
            length += float(np.linalg.norm(piece[0] - pieces[-1][-1]))
        else:
            piece, part = _chords(seg)
            length += part
        if length > MAX_SVG_LENGTH:
            _not_too_long(length, name, at_least=True)
        pieces.append(piece)
    pts = np.concatenate(pieces)
    _within_reach(pts, name, "the path")
    keep = np.concatenate([[True], np.linalg.norm(np.diff(pts, axis=0), axis=1) > 1e-9])
    pts = pts[keep]
    if len(pts) < 2:
        raise ValueError(f"{name}: the path has no length")
    return pts


def _chords(seg) -> tuple[np.ndarray, float]:
    """(points after the start, length) of a curve cut into chords of at most about CHORD
    (evenly in its parameter): its length measured on :data:`_SAMPLES` chords first."""
    t = np.linspace(0.0, 1.0, _SAMPLES + 1)
    first = _to_m(seg.npoint(t))
    length = float(np.linalg.norm(np.diff(first, axis=0), axis=1).sum())
    n = max(2, math.ceil(length / CHORD))
    if n <= _SAMPLES:  # a divisor of _SAMPLES, no fewer chords than asked
        step = _SAMPLES // 2 ** math.ceil(math.log2(n))
        return first[step::step], length
    return _to_m(seg.npoint(np.linspace(0.0, 1.0, n + 1)[1:])), length


def _within_reach(xy: np.ndarray, name: str, what: str) -> None:
    far = float(np.abs(xy).max(initial=0.0))
    if not far <= MAX_SVG_REACH:
        raise ValueError(f"{name}: {what} lies {far:.3g} m from the drawing's origin; at most "
                         f"{MAX_SVG_REACH:,g} m (are the drawing's units right?)")


def _not_too_long(length: float, name: str, at_least: bool) -> None:
    if length > MAX_SVG_LENGTH:
        raise ValueError(f"{name}: the path is too long to follow: "
                         f"{'at least ' if at_least else ''}{length:,.4g} m; at most "
                         f"{MAX_SVG_LENGTH:g} m")


def _to_m(points) -> np.ndarray:
    """(n, 2) svgelements pixels (y down) as metres, y up."""
    return np.asarray(points, float).reshape(-1, 2) * [PX_TO_M, -PX_TO_M]


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
