"""Physical uncertainty as data: how far a real table's friction, masses and restitution may
be from the scenario's, and one seeded draw of them applied to a scene.

A :class:`PhysicsRanges` states relative half-widths per property; a :class:`PhysicsDraw`
(ranges, seed, draw index) multiplies each rigid body's properties by factors uniform in
``[1 - r, 1 + r]``:

* friction: lateral, rolling and spinning by the same factor (a zero stays zero);
* mass: the body's mass (or density), so its inertia, computed from the mass when the world
  is built, scales with it;
* restitution: ``e * factor`` clipped to ``[0, 1]`` (a zero stays zero).

Factors are drawn **per rigid body**, from a generator seeded by ``(seed, index, body
name)``: the same seed and index give the same factors to the same body in any layout, any
method and any process (common random numbers), and a scene with other bodies does not shift
them. The bodies of a weld group move as one rigid body and take the factors of the group's
first member. Factors are rounded to steps of 1e-3, far below any measurement of friction or
mass, which bounds the mass-dependent data a simulation process caches per part.
Zero-width ranges return the scene itself: the simulation is exactly the unperturbed one.
A :class:`PhysicsCorner` is no draw but an end of every range for every body at once (the
worlds of ``optimize --physics-corners``).

Where a hand put each part (``position``, ``heading``; off by default)
-----------------------------------------------------------------------
Placement errors of the design space move only the free parameters; a maker also places every
fixed part by hand. With ``position`` (m) or ``heading`` (degrees), each part object gets its
own offsets, uniform in ``+-position`` along its parent frame's x and y and ``+-heading``
about its parent frame's z (a part on a plank slides along the plank), added to its
parent-relative pose. Not moved: frames (a domino run's dominoes move one by one), infinite
planes, and objects joined to another object by a hinge or weld (they move with their parent,
or their joint would be torn apart at the first step). Offsets are drawn from ``(seed, index,
object name, attempt)``. A hand does not push a part into another: when the placed layout
is not valid, the simulation draws again the objects whose bodies intersect (their next
attempt; :data:`PLACEMENT_SCALES`: full size eight times, then halved, at last where
designed) until it is.
"""

from __future__ import annotations

import dataclasses
import hashlib
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from rgmcad.errors import UsageError
from rgmcad.scene.bodies import Scene, SceneBody
from rgmcad.scene.model import FRAME, Scenario

__all__ = ["PhysicsRanges", "PhysicsDraw", "PhysicsCorner", "DEFAULT_PHYSICS",
           "PLACEMENT_SCALES", "parse_physics_ranges", "corner_worlds", "layout_draw",
           "hand_placed_objects", "placement_groups"]

_STEP = 1e-3
_PHYSICS_STREAM = 0x5048_5953  # keeps physics draws apart from any placement stream
_HAND_STREAM = 0x48_414E_44  # and a hand's offsets apart from both

PLACEMENT_SCALES = (1.0,) * 8 + (0.5, 0.25, 0.125, 0.0)
"""Sizes of an object's offsets at its attempts 0, 1, ...: eight full-size draws, then
smaller ones, at last none (where designed), so every layout finds a valid placement."""
_LIMITS = {"friction": 0.9, "mass": 0.9, "restitution": 1.0, "position": 0.05, "heading": 10.0}
_HINTS = {"position": "metres (0.002 is +-2 mm)", "heading": "degrees (1 is +-1 degree)"}


@dataclass(frozen=True)
class PhysicsRanges:
    """Relative half-widths of the physical perturbation (0.2: factors in [0.8, 1.2]), and
    absolute half-widths of where a hand puts each part.

    Attributes
    ----------
    friction : float, in [0, 0.9]
        Lateral, rolling and spinning friction (default 0.2, +-20 %).
    mass : float, in [0, 0.9]
        Mass, and with it inertia (default 0.1, +-10 %).
    restitution : float, in [0, 1]
        Restitution, clipped to [0, 1] after scaling (default 0.2, +-20 %).
    position : float, in [0, 0.05]
        Metres: every part's x and y in its parent's frame (default 0: off).
    heading : float, in [0, 10]
        Degrees: every part's heading (default 0: off).
    """

    friction: float = 0.2
    mass: float = 0.1
    restitution: float = 0.2
    position: float = 0.0
    heading: float = 0.0

    def __post_init__(self):
        for key, high in _LIMITS.items():
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not 0.0 <= value <= high:
                hint = _HINTS.get(key, "relative range (0.2 is +-20 %)")
                raise UsageError("physics", key, f"expected a {hint} from 0 to {high}, "
                                 f"got {value!r}")

    @property
    def zero(self) -> bool:
        return not self.changes_physics and not self.moves_parts

    @property
    def changes_physics(self) -> bool:
        """Whether friction, mass or restitution is perturbed."""
        return not self.friction == self.mass == self.restitution == 0.0

    @property
    def moves_parts(self) -> bool:
        """Whether a hand's placement errors move every part."""
        return self.position > 0.0 or self.heading > 0.0

    def describe(self) -> str:
        terms = []
        if self.changes_physics:
            terms.append(f"friction +-{self.friction:.0%}, mass +-{self.mass:.0%}, "
                         f"restitution +-{self.restitution:.0%}")
        if self.moves_parts:
            terms.append(f"every part within +-{self.position * 1000:g} mm and "
                         f"+-{self.heading:g} deg of its place")
        return ", ".join(terms) or "none"

    def to_json(self) -> dict:
        """The ranges as JSON; a hand's ranges only when set (so runs and benchmark trials
        made before they existed read as the same settings)."""
        out = dataclasses.asdict(self)
        for key in ("position", "heading"):
            if out[key] == 0.0:
                del out[key]
        return out


DEFAULT_PHYSICS = PhysicsRanges()


def parse_physics_ranges(text: str, where: str = "--physics") -> PhysicsRanges | None:
    """``"off"`` -> None; ``"default"`` or ``"friction=0.3,mass=0.05"`` (unnamed keys keep
    their default) -> :class:`PhysicsRanges`; anything else: UsageError naming ``where``."""
    text = text.strip()
    if text == "off":
        return None
    if text == "default":
        return DEFAULT_PHYSICS
    keys = [f.name for f in dataclasses.fields(PhysicsRanges)]
    given = {}
    for item in text.split(","):
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or key not in keys:
            raise UsageError(where, repr(item), "expected 'off', 'default' or KEY=VALUE,... "
                             f"with KEY one of {', '.join(keys)}")
        try:
            given[key] = float(value)
        except ValueError:
            raise UsageError(where, key, f"expected a number, got {value.strip()!r}") from None
    try:
        return PhysicsRanges(**given)
    except UsageError as error:
        raise UsageError(where, error.key, error.message) from None


@dataclass(frozen=True)
class PhysicsDraw:
    """Draw number ``index`` of the perturbation ``ranges`` under ``seed``."""

    ranges: PhysicsRanges
    seed: int
    index: int
    moved: frozenset[str] | None = None
    """The objects a hand misplaces (None: every hand-placed object); the others stay where
    designed. An object's offsets do not depend on which others move (common random numbers:
    draw ``index`` of one part alone is that part's offsets in the full draw ``index``)."""

    def factors(self, body: str) -> tuple[float, float, float]:
        """(friction, mass, restitution) factors of the rigid body named ``body``."""
        r = self.ranges
        key = (_PHYSICS_STREAM, int(self.index), zlib.crc32(body.encode()))
        u = np.random.default_rng(np.random.SeedSequence(int(self.seed), spawn_key=key))
        f, m, e = u.uniform(-1.0, 1.0, 3) * (r.friction, r.mass, r.restitution)
        return tuple(round(float(1.0 + v) / _STEP) * _STEP for v in (f, m, e))

    def apply(self, scene: Scene) -> Scene:
        """The scene with every body's physical properties perturbed (the scene itself when
        every range is zero)."""
        return _applied(self, scene)


    def offsets(self, movable: Iterable[str], attempts: Mapping[str, int] | None = None
                ) -> dict[str, np.ndarray]:
        """Where a hand put each object of ``movable``: ``{name: (6,) offset of its
        parent-relative pose (x, y, z, heading, pitch, roll)}``, the object's draw number
        ``attempts[name]`` (default 0) scaled by ``PLACEMENT_SCALES`` of it (empty when no
        hand's ranges are set)."""
        r = self.ranges
        if not r.moves_parts:
            return {}
        attempts = attempts or {}
        out = {}
        for name in movable:
            if self.moved is not None and name not in self.moved:
                continue
            attempt = min(int(attempts.get(name, 0)), len(PLACEMENT_SCALES) - 1)
            key = (_HAND_STREAM, int(self.index), zlib.crc32(name.encode()), attempt)
            u = np.random.default_rng(np.random.SeedSequence(int(self.seed), spawn_key=key))
            dx, dy, dh = u.uniform(-1.0, 1.0, 3) * PLACEMENT_SCALES[attempt] * np.array(
                (r.position, r.position, r.heading))
            out[name] = np.array([dx, dy, 0.0, dh, 0.0, 0.0])
        return out


@dataclass(frozen=True)
class PhysicsCorner:
    """One end of every range for every body: ``high`` gives each factor ``1 + r``, else
    ``1 - r``. Pybullet combines two bodies' friction by their product, so every contact's
    friction is then at its own end too (0.64 or 1.44 of the scenario's at +-20 %): the
    slipperiest table a draw can give, or the grippiest. Parts are where designed."""

    ranges: PhysicsRanges
    high: bool

    def __post_init__(self):  # run.simulate reads ranges.moves_parts
        object.__setattr__(self, "ranges", dataclasses.replace(
            self.ranges, position=0.0, heading=0.0))

    def factors(self, body: str) -> tuple[float, float, float]:
        r, sign = self.ranges, (1.0 if self.high else -1.0)
        return tuple(round((1.0 + sign * v) / _STEP) * _STEP
                     for v in (r.friction, r.mass, r.restitution))

    def apply(self, scene: Scene) -> Scene:
        return _applied(self, scene)


def corner_worlds(ranges: PhysicsRanges) -> tuple[PhysicsCorner, PhysicsCorner]:
    """The low and the high corner of ``ranges``."""
    return PhysicsCorner(ranges, False), PhysicsCorner(ranges, True)


def _applied(draw, scene: Scene) -> Scene:
    if not draw.ranges.changes_physics:
        return scene
    first = {name: group[0] for group in scene.welds for name in group}
    bodies = {name: _perturbed(body, draw.factors(first.get(name, name)))
              for name, body in scene.bodies.items()}
    return dataclasses.replace(scene, bodies=bodies)


def hand_placed_objects(scenario: Scenario, infinite: Iterable[str] = ()) -> list[str]:
    """The objects a hand places one by one, in file order: every part object except infinite
    planes (``infinite``: their names) and objects joined to others by hinges or welds; of
    such a group only the member that all the others descend from is placed (they follow
    it), and none when there is no such member (moving one would tear its joints apart)."""
    group: dict[str, set[str]] = {}
    for joint in scenario.joints:
        if len(joint.objects) > 1:
            merged = set(joint.objects).union(*(group.get(n, set()) for n in joint.objects))
            for name in merged:
                group[name] = merged

    def ancestors(name):
        out, parent = set(), scenario.objects[name].parent
        while parent is not None:
            out.add(parent)
            parent = scenario.objects[parent].parent
        return out

    skip = set(infinite)
    for name, members in group.items():
        others = members - {name}
        if not all(name in ancestors(o) for o in others):
            skip.add(name)
    return [obj.name for obj in scenario.objects.values()
            if obj.part != FRAME and obj.name not in skip]


def placement_groups(scenario: Scenario, infinite: Iterable[str] = ()) -> dict[str, list[str]]:
    """:func:`hand_placed_objects` as a maker names them: the objects placed in one frame
    (a domino run's dominoes) under the frame's name, every other object under its own."""
    groups: dict[str, list[str]] = {}
    for name in hand_placed_objects(scenario, infinite):
        parent = scenario.objects[name].parent
        frame = parent is not None and scenario.objects[parent].part == FRAME
        groups.setdefault(parent if frame else name, []).append(name)
    return groups


def _perturbed(body: SceneBody, factors: tuple[float, float, float]) -> SceneBody:
    f, m, e = factors
    p = body.physical
    physical = dataclasses.replace(
        p, mass=None if p.mass is None else p.mass * m,
        density=None if p.density is None else p.density * m,
        friction=p.friction * f, rolling_friction=p.rolling_friction * f,
        spinning_friction=p.spinning_friction * f,
        restitution=min(max(p.restitution * e, 0.0), 1.0))
    return dataclasses.replace(body, physical=physical)


def layout_draw(ranges: PhysicsRanges, seed: int, x) -> PhysicsDraw:
    """The draw of the layout vector ``x`` (d,) (learning with physical noise): its index is
    a hash of ``x``'s float64 bytes, so every new layout gets its own draw and a layout
    simulated again (replayed from a run's journal, or in another process) the same one."""
    digest = hashlib.sha256(np.ascontiguousarray(x, dtype=np.float64).tobytes()).digest()
    return PhysicsDraw(ranges, seed, int.from_bytes(digest[:8], "little"))
