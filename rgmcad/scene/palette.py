"""The colours of a layout's parts: one table read by every picture of it (the PNG and video
renderer, :mod:`rgmcad.sim.render`; the 3D replay and the run report, :mod:`rgmcad.viewer`), so
a part has the same colour in all of them.

The rule, from the scene's order of objects alone (so the same layout is coloured the same
everywhere, and colours do not change as parts move):

- objects that move take the saturated colours of :data:`MOVING` in turn; a domino run takes
  one as a whole (at its first domino), its dominoes alternating that colour and a lighter
  shade of it, so neighbours stay apart;
- static objects take the muted tones of :data:`STATIC` in turn: structure, not actors;
- a body of an object other than its main one (a lever's fixed axle) is a darker shade of its
  object's colour;
- past the end of a list, the colours come round again darker, then lighter, then darker
  still, and so on: distinct objects never share a colour unless they are dominoes of one run;
- infinite planes are grey: :data:`FLOOR` when horizontal, :data:`BOARD` otherwise.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

__all__ = ["RGB", "MOVING", "STATIC", "FLOOR", "BOARD", "object_colours", "scene_colours",
           "plane_colour", "runs_of"]

RGB = tuple[float, float, float]

MOVING: tuple[RGB, ...] = (  # Tableau 10, its grey left to static parts
    (0.306, 0.475, 0.655), (0.949, 0.557, 0.169), (0.882, 0.341, 0.349),
    (0.463, 0.718, 0.698), (0.349, 0.631, 0.310), (0.929, 0.788, 0.282),
    (0.690, 0.478, 0.631), (1.000, 0.616, 0.655), (0.612, 0.459, 0.373))
STATIC: tuple[RGB, ...] = (  # stone, slate, sand, sage, clay, heather, steel, khaki
    (0.660, 0.640, 0.600), (0.520, 0.570, 0.630), (0.760, 0.700, 0.560),
    (0.580, 0.640, 0.540), (0.680, 0.560, 0.500), (0.620, 0.570, 0.660),
    (0.700, 0.730, 0.760), (0.600, 0.580, 0.460))
FLOOR: RGB = (0.871, 0.859, 0.831)
BOARD: RGB = (0.940, 0.930, 0.910)

_BLACK, _WHITE = (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)


def _mix(a: RGB, b: RGB, w: float) -> RGB:
    return tuple(round((1 - w) * x + w * y, 3) for x, y in zip(a, b, strict=True))


def _nth(colours: tuple[RGB, ...], k: int) -> RGB:
    """The k-th colour of a list, coming round darker (odd rounds) or lighter (even ones),
    a little more each time round."""
    base, lap = colours[k % len(colours)], k // len(colours)
    if lap == 0:
        return base
    step = (lap + 1) // 2
    return _mix(base, _BLACK if lap % 2 else _WHITE, min(0.22 * step, 0.66) + 0.001 * lap)


def object_colours(objects: Iterable[tuple[str, bool, str | None]]) -> dict[str, RGB]:
    """Object name -> colour, for ``(name, static, run)`` of each object in the scene's order
    (``run``: the domino run it belongs to, or None)."""
    out: dict[str, RGB] = {}
    runs: dict[str, tuple[RGB, int]] = {}  # run -> its colour, dominoes coloured so far
    moving = static = 0
    for name, fixed, run in objects:
        if name in out:
            continue
        if run is not None and not fixed:
            if run not in runs:
                runs[run] = (_nth(MOVING, moving), 0)
                moving += 1
            colour, n = runs[run]
            runs[run] = (colour, n + 1)
            out[name] = _mix(colour, _WHITE, 0.3) if n % 2 else colour
        elif fixed:
            out[name] = _nth(STATIC, static)
            static += 1
        else:
            out[name] = _nth(MOVING, moving)
            moving += 1
    return out


def scene_colours(scene, runs: Mapping[str, str] | None = None) -> dict[str, RGB]:
    """Body name -> colour of every body of ``scene`` (a :class:`~rgmcad.scene.bodies.Scene`)
    but its infinite planes; ``runs``: object name -> its domino run (:func:`runs_of`)."""
    runs = runs or {}
    solid = [b for b in scene.bodies.values() if not b.plane]
    main = {b.object: b.static for b in solid if b.name == b.object}
    colours = object_colours((b.object, main.get(b.object, b.static), runs.get(b.object))
                             for b in solid)
    return {b.name: colours[b.object] if b.name == b.object else _mix(colours[b.object],
                                                                       _BLACK, 0.35)
            for b in solid}


def runs_of(scenario) -> dict[str, str]:
    """Object name -> its domino run's name, for the objects of ``scenario`` in a run."""
    return {o.name: o.run for o in scenario.objects.values() if o.run is not None}


def plane_colour(pose) -> RGB:
    """The colour of an infinite plane of world transform ``pose`` (4, 4; +z its normal)."""
    return FLOOR if abs(float(np.asarray(pose)[2, 2])) > 0.5 else BOARD
