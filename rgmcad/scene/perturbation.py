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
"""

from __future__ import annotations

import dataclasses
import hashlib
import zlib
from dataclasses import dataclass

import numpy as np

from rgmcad.errors import UsageError
from rgmcad.scene.bodies import Scene, SceneBody

__all__ = ["PhysicsRanges", "PhysicsDraw", "DEFAULT_PHYSICS", "parse_physics_ranges",
           "layout_draw"]

_STEP = 1e-3
_PHYSICS_STREAM = 0x5048_5953  # keeps physics draws apart from any placement stream


@dataclass(frozen=True)
class PhysicsRanges:
    """Relative half-widths of the physical perturbation (0.2: factors in [0.8, 1.2]).

    Attributes
    ----------
    friction : float, in [0, 0.9]
        Lateral, rolling and spinning friction (default 0.2, +-20 %).
    mass : float, in [0, 0.9]
        Mass, and with it inertia (default 0.1, +-10 %).
    restitution : float, in [0, 1]
        Restitution, clipped to [0, 1] after scaling (default 0.2, +-20 %).
    """

    friction: float = 0.2
    mass: float = 0.1
    restitution: float = 0.2

    def __post_init__(self):
        for key, high in (("friction", 0.9), ("mass", 0.9), ("restitution", 1.0)):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not 0.0 <= value <= high:
                raise UsageError("physics", key, f"expected a relative range from 0 to {high} "
                                 f"(0.2 is +-20 %), got {value!r}")

    @property
    def zero(self) -> bool:
        return self.friction == self.mass == self.restitution == 0.0

    def describe(self) -> str:
        return (f"friction +-{self.friction:.0%}, mass +-{self.mass:.0%}, "
                f"restitution +-{self.restitution:.0%}")

    def to_json(self) -> dict:
        return dataclasses.asdict(self)


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
            raise UsageError(where, repr(item), "expected 'off', 'default' or KEY=RANGE,... "
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
        if self.ranges.zero:
            return scene
        first = {name: group[0] for group in scene.welds for name in group}
        bodies = {name: _perturbed(body, self.factors(first.get(name, name)))
                  for name, body in scene.bodies.items()}
        return dataclasses.replace(scene, bodies=bodies)


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
