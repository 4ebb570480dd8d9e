"""Ropes of one layout, resolved to world points (pure data), and how long they must be.

A rope runs from its first end over fixed pulley points to its second end; its length along
that path may never exceed the rope's length. An end on a moving body moves with it; an end
on a static body, a frame or the world is fixed, like the pulleys.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rgmcad.scene.model import Rope, RopePoint, Scenario


@dataclass(frozen=True, eq=False)
class SceneRope:
    """``bodies``: the scene body each end is tied to (None: a fixed end), with ``local`` (2, 3)
    the points in those bodies' part frames; ``points`` (k + 2, 3): world points of the path
    at the start (first end, k pulleys, second end); ``length`` m; ``objects``: the object
    each point of the path belongs to (None: the world)."""

    name: str
    bodies: tuple[str | None, str | None]
    local: np.ndarray
    points: np.ndarray
    length: float
    objects: tuple[str | None, ...] = ()

    @property
    def initial_length(self) -> float:
        return path_length(self.points)

    @property
    def excess(self) -> float:
        """How much longer (m) the path is at the start than the rope: > 0 is too short."""
        return self.initial_length - self.length


def path_length(points: np.ndarray) -> float | np.ndarray:
    """Length (m) of the polyline ``points`` (..., k, 3)."""
    return np.linalg.norm(np.diff(points, axis=-2), axis=-1).sum(axis=-1)


def _moving(scenario: Scenario, at: RopePoint) -> bool:
    return at.object is not None and not scenario.objects[at.object].physical.static


def path_of(rope: Rope) -> tuple[RopePoint, ...]:
    """The rope's points in order: first end, pulleys, second end."""
    return (rope.ends[0], *rope.pulleys, rope.ends[1])


def world_points(scenario: Scenario, rope: Rope, poses: Mapping[str, np.ndarray]) -> np.ndarray:
    """(..., k + 2, 3) world points of the rope's path, for poses (..., 4, 4) of every object."""
    out = []
    for at in path_of(rope):
        p = np.asarray(at.point, float)
        if at.object is None:
            out.append(np.broadcast_to(p, next(iter(poses.values())).shape[:-2] + (3,)))
        else:
            pose = poses[at.object]
            out.append(np.einsum("...ij,j->...i", pose[..., :3, :3], p) + pose[..., :3, 3])
    return np.stack(out, axis=-2)


def scene_ropes(scenario: Scenario, poses: Mapping[str, np.ndarray]) -> tuple[SceneRope, ...]:
    """The scenario's ropes for one layout's world poses (every object's (4, 4))."""
    out = []
    for rope in scenario.ropes.values():
        points = world_points(scenario, rope, poses)
        length = rope.length if rope.length is not None else path_length(points) + rope.slack
        out.append(SceneRope(
            rope.name,
            tuple(e.object if _moving(scenario, e) else None for e in rope.ends),
            np.array([e.point for e in rope.ends], float), points, float(length),
            tuple(at.object for at in path_of(rope))))
    return tuple(out)


def ropes_fit_many(scenario: Scenario, world: Mapping[str, np.ndarray],
                   tolerance: float) -> np.ndarray:
    """(m,) bool: whether every rope of a given length reaches its path (within ``tolerance``
    m) in each of m layouts, for world poses (m, 4, 4) of every object."""
    m = len(next(iter(world.values())))
    fits = np.ones(m, dtype=bool)
    for rope in scenario.ropes.values():
        if rope.length is not None:
            fits &= path_length(world_points(scenario, rope, world)) - rope.length <= tolerance
    return fits
