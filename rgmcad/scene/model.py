"""A scenario as data: its objects, free parameters, joints, events and settings.

Frozen values only; :mod:`rgmcad.scene.loader` reads them from a scenario file and checks
them. Physics, events and the causal monitor read these types, never the file.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rgmcad.geometry import ANGLE_KEYS
from rgmcad.parts.family import MAIN, Family
from rgmcad.scene.eventspec import Negation

FRAME = "frame"
"""Part name of a pure reference frame: it has no body and carries poses for its children."""


@dataclass(frozen=True)
class Physical:
    """Physical properties of an object's main body (SI units).

    Neither ``mass`` nor ``density``: the body is static. Friction and restitution combine by
    product between two bodies (Bullet's rule). Damping is zero unless asked for.
    """

    mass: float | None = None  # kg
    density: float | None = None  # kg/m^3
    friction: float = 0.5
    restitution: float = 0.0
    linear_damping: float = 0.0
    angular_damping: float = 0.0
    rolling_friction: float = 0.0
    spinning_friction: float = 0.0

    @property
    def static(self) -> bool:
        return self.mass is None and self.density is None


PHYSICAL_KEYS = tuple(f.name for f in dataclasses.fields(Physical))


@dataclass(frozen=True)
class SceneObject:
    """One object: a part instance (or a frame) posed relative to its parent.

    ``pose`` is ``(x, y, z, heading, pitch, roll)`` in metres and degrees, relative to the
    parent's frame (the world when ``parent`` is None).
    """

    name: str
    part: str  # family name, or FRAME
    params: Any  # the family's Params instance; None for frames
    physical: Physical
    parent: str | None
    pose: tuple[float, ...]
    run: str | None = None  # the domino run it belongs to


@dataclass(frozen=True)
class FreeParameter:
    """A pose component left free for the layout, with its range in real units."""

    object: str
    component: str  # one of POSE_KEYS
    low: float
    high: float

    @property
    def name(self) -> str:
        return f"{self.object}.{self.component}"

    @property
    def unit(self) -> str:
        return "deg" if self.component in ANGLE_KEYS else "m"


@dataclass(frozen=True)
class Joint:
    """A joint declared in the scenario (parts bring their own, e.g. a lever's hinge).

    ``weld``: ``objects`` move as one rigid body. ``hinge``: ``objects[0]`` turns about the axis
    ``axis`` through ``point`` (both in its own frame), relative to ``objects[1]`` or the world.
    """

    kind: str  # "weld" | "hinge"
    objects: tuple[str, ...]
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)
    axis: tuple[float, float, float] = (0.0, 1.0, 0.0)


@dataclass(frozen=True)
class RopePoint:
    """A point a rope is tied to or runs over: ``point`` (3,) m in the part frame of
    ``object``, or in the world when ``object`` is None. A point of a static body or of a
    frame stays where the layout puts it."""

    object: str | None
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Rope:
    """An inextensible rope that can go slack and only pulls (see :mod:`rgmcad.sim.ropes`).

    It runs from ``ends[0]`` over the fixed ``pulleys`` points, in order, to ``ends[1]``;
    its length is ``length`` (m), or, when that is None, the layout's initial length plus
    ``slack`` (m): the authors' tension rope, which every layout fits.
    """

    name: str
    ends: tuple[RopePoint, RopePoint]
    pulleys: tuple[RopePoint, ...] = ()
    length: float | None = None
    slack: float = 0.0


@dataclass(frozen=True)
class EventSpec:
    """One node of the causal graph.

    ``negate`` is a :class:`~rgmcad.scene.eventspec.Negation` (a bool is read as OFF / ONCE).
    ``point`` or ``end`` (events whose type ``takes_point``; at most one) name the point of the
    body whose motion counts: coordinates in the body's part frame, or the centre of one face
    of its bounding box (one of :data:`~rgmcad.scene.eventspec.ENDS`). Neither: the centre of mass.
    """

    name: str
    type: str
    objects: dict[str, str]  # role -> object name
    params: dict[str, float]
    after: tuple[str, ...] = ()
    join: str = "all"  # "all" | "any"
    negate: Negation = Negation.OFF
    hold: float = 0.0  # s the condition must hold before success
    timeout: float | None = None  # s after waking; None = the scenario's event_timeout
    description: str = ""
    point: tuple[float, float, float] | None = None  # m, in the body's part frame
    end: str | None = None  # "+x" | "-x" | "+y" | "-y" | "+z" | "-z"

    def __post_init__(self):
        if not isinstance(self.negate, Negation):
            object.__setattr__(self, "negate", Negation(bool(self.negate)))


@dataclass(frozen=True)
class SimulationSettings:
    """Every setting that changes a trajectory, pinned (pybullet's defaults drift by version).

    Defaults follow the paper's engine where it matters (time step 1/500 s, 2 s event timeout,
    10 solver iterations, no split impulse); ``ccd`` enables continuous collision detection for
    small fast bodies, which the paper's engine lacked. ``solver_residual_threshold``: the
    solver stops iterating once the sum of squared impulse changes of an iteration is below it
    (pybullet's default; larger values save 5-15 % on large scenes and move outcomes,
    docs/decisions.md, "Simulating at the physics floor, second pass").
    """

    timestep: float = 0.002
    duration: float = 4.0
    event_timeout: float = 2.0
    gravity: float = 9.81
    solver_iterations: int = 10
    erp: float = 0.2
    contact_erp: float = 0.2
    friction_erp: float = 0.2
    split_impulse: bool = False
    contact_breaking_threshold: float = 0.002
    restitution_velocity_threshold: float = 0.05
    convex_margin: float = 1e-4
    ccd: bool = True
    solver_residual_threshold: float = 1e-7


SIMULATION_KEYS = tuple(f.name for f in dataclasses.fields(SimulationSettings))


@dataclass(frozen=True)
class Scenario:
    name: str
    path: Path | None
    description: str
    objects: dict[str, SceneObject]  # file order; domino runs expanded
    free: tuple[FreeParameter, ...]  # design-vector order
    joints: tuple[Joint, ...]
    events: dict[str, EventSpec]  # file order
    settings: SimulationSettings
    layouts: dict[str, dict[str, float]]  # name -> {free parameter name: real value}
    families: dict[str, Family] = field(repr=False, default_factory=dict)
    runs: dict[str, tuple[str, ...]] = field(default_factory=dict)  # run -> domino names
    ropes: dict[str, Rope] = field(default_factory=dict)  # file order

    @property
    def dimension(self) -> int:
        return len(self.free)

    @property
    def root_event(self) -> str:
        return next(n for n, e in self.events.items() if not e.after)

    def family(self, obj: SceneObject) -> Family:
        return self.families[obj.part]

    def body_objects(self) -> list[SceneObject]:
        """Objects that are parts (frames excluded), in file order."""
        return [o for o in self.objects.values() if o.part != FRAME]


def body_key(body: str) -> tuple[str, str]:
    """Split a body name into (object name, part body key)."""
    obj, _, sub = body.partition(".")
    return obj, sub or MAIN
