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
  still (three times each way), and a colour some part has already is nudged to the next free
  one: distinct objects never share a colour unless they are dominoes of one run;
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
    return _mix(base, _BLACK if lap % 2 else _WHITE, min(0.22 * ((lap + 1) // 2), 0.66))


def _unused(colour: RGB, used: set[RGB]) -> RGB:
    """``colour``, or, when a part has it already (hundreds of parts come round to the same
    shades), the next free one in steps of 0.001 (blue first): every part its own colour."""
    n = sum(round(c * 1000) * 1001 ** i for i, c in enumerate(reversed(colour)))
    while colour in used:
        n = (n + 1) % 1001 ** 3
        colour = (n // 1001 ** 2 / 1000, n // 1001 % 1001 / 1000, n % 1001 / 1000)
    used.add(colour)
    return colour


def object_colours(objects: Iterable[tuple[str, bool, str | None]]) -> dict[str, RGB]:
    """Object name -> colour, for ``(name, static, run)`` of each object in the scene's order
    (``run``: the domino run it belongs to, or None)."""
    out: dict[str, RGB] = {}
    used: set[RGB] = set()
    runs: dict[str, list] = {}  # run -> [its colour, its lighter shade, dominoes so far]
    moving = static = 0
    for name, fixed, run in objects:
        if name in out:
            continue
        if run is not None and not fixed:
            if run not in runs:
                colour = _unused(_nth(MOVING, moving), used)
                runs[run] = [colour, _unused(_mix(colour, _WHITE, 0.3), used), 0]
                moving += 1
            shades = runs[run]
            out[name] = shades[shades[2] % 2]
            shades[2] += 1
        elif fixed:
            out[name] = _unused(_nth(STATIC, static), used)
            static += 1
        else:
            out[name] = _unused(_nth(MOVING, moving), used)
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
    used = set(colours.values())
    darker: dict[str, RGB] = {}  # object -> the colour of its other bodies
    for b in solid:
        if b.name != b.object and b.object not in darker:
            darker[b.object] = _unused(_mix(colours[b.object], _BLACK, 0.35), used)
    return {b.name: colours[b.object] if b.name == b.object else darker[b.object]
            for b in solid}


def runs_of(scenario) -> dict[str, str]:
    """Object name -> its domino run's name, for the objects of ``scenario`` in a run."""
    return {o.name: o.run for o in scenario.objects.values() if o.run is not None}


def plane_colour(pose) -> RGB:
    """The colour of an infinite plane of world transform ``pose`` (4, 4; +z its normal)."""
    return FLOOR if abs(float(np.asarray(pose)[2, 2])) > 0.5 else BOARD
