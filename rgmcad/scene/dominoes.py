"""Domino run paths: where each domino of a run stands, in the run's own frame.

Every generator returns an ``(n, 3)`` array of ``(x, y, heading_deg)``: the domino's centre on
the ground plane of the run frame and the direction it falls in (its local +X). A heading that
differs by 180 degrees is the same physical domino.

The shapes follow the paper's helpers (line, arc, wave, Y branch, X switch), written anew, with
one fix: the wave's ``angle`` is in degrees like every other angle (the authors' helper read it
as radians; harmless there because every scenario used 0).
"""

from __future__ import annotations

import numpy as np

from rgmcad.geometry import atan2_degrees, exp, matmul, rotation_2d, sin_cos_degrees


def _place(points: np.ndarray, headings: np.ndarray, origin, angle_deg: float) -> np.ndarray:
    """Rotate (n, 2) points and headings by ``angle_deg`` and move them to ``origin``."""
    xy = matmul(points, rotation_2d(angle_deg).T) + np.asarray(origin, float)
    return np.column_stack([xy, headings + angle_deg])


def line(count: int, length: float, origin=(0.0, 0.0), angle: float = 0.0) -> np.ndarray:
    """``count`` dominoes evenly spaced over ``length`` metres along direction ``angle``."""
    x = np.linspace(0.0, length, count)
    return _place(np.column_stack([x, np.zeros(count)]), np.zeros(count), origin, angle)


def arc(count: int, radius: float, start: float, end: float, center=(0.0, 0.0)) -> np.ndarray:
    """``count`` dominoes on a circular arc from polar angle ``start`` to ``end`` (degrees).

    Each domino faces along the arc (heading = polar angle + 90), so the run falls in the
    direction of increasing angle when ``end > start``.
    """
    polar = np.linspace(start, end, count)
    sin, cos = sin_cos_degrees(polar)
    pts = radius * np.column_stack([cos, sin])
    headings = polar + (90.0 if end >= start else -90.0)
    return _place(pts, headings, center, 0.0)


_WAVE_PEAK = 0.5235731  # max over u of exp(-u^2/2) sin(u), reached at u = 1


def wave(count: int, length: float, width: float, origin=(0.0, 0.0), angle: float = 0.0):
    """``count`` dominoes evenly spaced by arc length on a single S-shaped wave.

    The centre line is ``y = (width/2) * exp(-u^2/2) sin(u) / peak`` with
    ``u = pi (2 x / length - 1)``, so the run starts and ends on the x axis and swings
    ``width/2`` to either side. Headings follow the local tangent.
    """
    x = np.linspace(0.0, length, 4001)
    k = (width / 2) / _WAVE_PEAK
    u = np.pi * (2 * x / length - 1)
    y = k * exp(-(u**2) / 2) * sin_cos_degrees(u * (180.0 / np.pi))[0]
    dy = np.gradient(y, x)
    f = np.sqrt(1 + dy**2)  # cumulative trapezoid (scipy.integrate costs 0.8 s to import)
    s = np.concatenate([[0.0], np.cumsum(np.diff(x) * (f[1:] + f[:-1]) / 2.0)])
    targets = np.linspace(0.0, s[-1], count)
    xs = np.interp(targets, s, x)
    ys = np.interp(targets, s, y)
    heading = atan2_degrees(np.interp(targets, s, dy), 1.0)
    return _place(np.column_stack([xs, ys]), heading, origin, angle)


def branch(arm_count: int, length: float, width: float, origin=(0.0, 0.0), angle: float = 0.0):
    """A Y fork of ``3 * arm_count`` dominoes: a trunk, then two arms splitting sideways.

    The trunk and each arm have ``arm_count`` dominoes, spaced evenly in x over ``length``. Each
    arm moves sideways in equal steps until it is ``width/2`` off the axis; its last domino
    stands at ``width/2``. Indices: trunk ``0..n-1``, left arm (+y) ``n..2n-1``, right arm
    (-y) ``2n..3n-1``; the run's tips are ``2n-1`` and ``3n-1``.
    """
    n = arm_count
    if n < 2:
        raise ValueError("a branch needs at least 2 dominoes per arm")
    x = np.linspace(0.0, length, 2 * n)
    side = np.minimum(np.arange(1, n + 1) * (width / 2) / (n - 1), width / 2)
    trunk = np.column_stack([x[:n], np.zeros(n)])
    left = np.column_stack([x[n:], side])
    right = np.column_stack([x[n:], -side])
    pts = np.vstack([trunk, left, right])
    return _place(pts, np.zeros(len(pts)), origin, angle)


def x_switch(count: int, width: float, origin=(0.0, 0.0), angle: float = 0.0) -> np.ndarray:
    """Two paths of ``count`` dominoes that cross once: a switch that remembers the winner.

    Path A starts at (0, 0) and path B at (0, -width); each turns by 45 degrees on a
    three-domino quarter arc of radius ``width/2``, runs diagonally through the shared centre
    domino (heading 0, so either diagonal can knock it over) and turns back on the other side,
    ending on the opposite line. Whichever path reaches the centre first knocks down the shared
    domino and the crossing path; only the first path's end falls. ``2 * count - 1`` dominoes:
    path A is ``0..count-1`` (the centre is ``(count - 1) // 2``), path B the rest.
    ``count`` must be odd and at least 7.
    """
    if count < 7 or count % 2 == 0:
        raise ValueError("an X switch needs an odd number of dominoes per path, at least 7")
    r = width / 2
    s45 = np.sqrt(0.5)
    # path A, descending from y = 0 to y = -width
    sin, cos = sin_cos_degrees([0.0, 22.5, 45.0])
    turn_in = [(r * s, -r + r * c, -a) for a, s, c in zip((0.0, 22.5, 45.0), sin, cos, strict=True)]
    start = np.array(turn_in[-1][:2])
    end = np.array([3 * r * s45, -r - r * s45])  # where the exit arc begins
    diagonal = [(*(start + t * (end - start)), -45.0) for t in np.linspace(0, 1, count - 4)[1:-1]]
    cx = 4 * r * s45
    turn_out = [(cx - r * s, -r - r * c, -a)
                for a, s, c in zip((45.0, 22.5, 0.0), sin[::-1], cos[::-1], strict=True)]
    path_a = np.array(turn_in + diagonal + turn_out)
    centre = (count - 1) // 2
    path_a[centre, 2] = 0.0
    path_b = path_a.copy()
    path_b[:, 1] = -width - path_a[:, 1]
    path_b[:, 2] = -path_a[:, 2]
    path_b = np.delete(path_b, centre, axis=0)
    pts = np.vstack([path_a, path_b])
    return _place(pts[:, :2], pts[:, 2], origin, angle)


def _segments(points):
    """(points (k, 2), segments (k-1, 2), their lengths) of a polyline, checked."""
    pts = np.asarray(points, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
        raise ValueError("a polyline needs at least two (x, y) points")
    seg = np.diff(pts, axis=0)
    seg_len = np.linalg.norm(seg, axis=1)
    if np.any(seg_len <= 0):
        raise ValueError("a polyline cannot repeat a point")
    return pts, seg, seg_len


def polyline_count(points, count: int | None = None, spacing: float | None = None) -> int:
    """How many dominoes :func:`polyline` places, computed without placing them."""
    if (count is None) == (spacing is None):
        raise ValueError("give exactly one of count or spacing")
    if count is not None:
        return count
    return int(np.floor(_segments(points)[2].sum() / spacing + 1e-9)) + 1


def polyline(points, count: int | None = None, spacing: float | None = None) -> np.ndarray:
    """Dominoes evenly spaced by arc length along a polyline of (k, 2) ``points``.

    Give either ``count`` or ``spacing`` (metres). Headings follow the segment under each
    domino; a domino exactly on a corner takes the mean direction of its two segments.
    """
    pts, seg, seg_len = _segments(points)
    total = seg_len.sum()
    count = polyline_count(points, count, spacing)
    s = np.linspace(0.0, total, count) if spacing is None else np.arange(count) * spacing
    cum = np.concatenate([[0.0], np.cumsum(seg_len)])
    idx = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(seg) - 1)
    t = (s - cum[idx]) / seg_len[idx]
    xy = pts[idx] + seg[idx] * t[:, None]
    direction = seg[idx] / seg_len[idx, None]
    on_corner = (np.abs(t) < 1e-9) & (idx > 0)
    prev = seg[idx - 1] / seg_len[idx - 1, None]
    direction = np.where(on_corner[:, None], direction + prev, direction)
    heading = atan2_degrees(direction[:, 1], direction[:, 0])
    return np.column_stack([xy, heading])


PATHS = {
    "line": line,
    "arc": arc,
    "wave": wave,
    "branch": branch,
    "x_switch": x_switch,
    "polyline": polyline,
}
"""Run path generators by the name used in scenario files (``path = { kind = "line", ... }``)."""


def overlaps(coords, thickness: float, width: float, tolerance: float, enough: int | None = None):
    """``(i, j, depth)`` arrays of the pairs ``i < j`` of dominoes of a run (``(n, 3)`` x, y,
    heading in degrees) whose footprints, ``thickness`` along the heading by ``width`` across,
    overlap by more than ``tolerance`` (m): neighbours first, then by ``i`` and ``j``; no
    further than the first block that brings them past ``enough``. The depth is the least
    overlap along the four sides' directions (separating axes). Standing dominoes of one run
    are the same box at the same height, so these are the pairs the validity check would
    intersect exactly. Milliseconds for a run of a thousand, in blocks of rows."""
    coords = np.asarray(coords, float)
    n, xy = len(coords), coords[:, :2]
    sin, cos = sin_cos_degrees(coords[:, 2])
    near = np.hypot(thickness, width)  # centres farther apart cannot overlap
    found, total = [], 0

    def add(i, j) -> bool:
        """Test the pairs (i, j); whether more than ``enough`` overlap so far."""
        nonlocal total
        depth = _footprint_overlap(xy[j] - xy[i], cos[i], sin[i], cos[j], sin[j], thickness,
                                   width)
        hit = depth > tolerance
        found.append((i[hit], j[hit], depth[hit]))
        total += int(hit.sum())
        return enough is not None and total > enough

    if not add(np.arange(n - 1), np.arange(1, n)):
        for start in range(0, n, 64):  # rows start..start+63 against every later domino
            rows = np.arange(start, min(start + 64, n))
            r, j = np.nonzero((np.linalg.norm(xy[rows, None] - xy[None], axis=2) < near)
                              & (np.arange(n)[None] > rows[:, None] + 1))
            if add(rows[r], j):
                break
    return tuple(np.concatenate(parts) for parts in zip(*found, strict=True))


def _footprint_overlap(gap, cos_i, sin_i, cos_j, sin_j, thickness, width):
    """Least overlap (m) of the footprints of pairs of equal dominoes, along the four
    directions of their sides (negative: apart), ``gap`` (p, 2) from the first to the
    second."""
    c = np.abs(cos_i * cos_j + sin_i * sin_j)  # |cos| and |sin| of the angle between them
    s = np.abs(sin_j * cos_i - cos_j * sin_i)
    along = (thickness + thickness * c + width * s) / 2  # reach of both along a long side
    across = (width + thickness * s + width * c) / 2
    gx, gy = gap[:, 0], gap[:, 1]
    return np.minimum.reduce([along - np.abs(gx * cos_i + gy * sin_i),
                              across - np.abs(-gx * sin_i + gy * cos_i),
                              along - np.abs(gx * cos_j + gy * sin_j),
                              across - np.abs(-gx * sin_j + gy * cos_j)])
