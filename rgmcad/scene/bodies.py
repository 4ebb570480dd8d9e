"""A scene: one layout of a scenario, resolved to posed rigid bodies and joints (pure data).

Validity and physics are both built from a :class:`Scene`; neither reads the scenario again.
Welded objects are merged into one rigid body here (an exact weld, with no solver
compliance); hinges stay joints.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rgmcad.geometry import matmul, norm, transform_points
from rgmcad.parts.build import Store, load_part
from rgmcad.parts.family import MAIN
from rgmcad.parts.store import DEFAULT_BUILD_DIR, BuiltBody, BuiltPart, as_store
from rgmcad.scene.design_space import world_poses
from rgmcad.scene.model import FRAME, Physical, Scenario
from rgmcad.scene.ropes import SceneRope, scene_ropes


@dataclass(frozen=True, eq=False)
class SceneBody:
    """One body of one object (an object may bring several: a lever and its axle).

    ``pose`` is the (4, 4) world transform of the part's frame; ``built`` holds its mesh, mass
    properties and collision pieces in that frame (None for an infinite plane).
    """

    name: str
    object: str
    built: BuiltBody | None
    pose: np.ndarray
    physical: Physical
    static: bool

    @property
    def plane(self) -> bool:
        return self.built is None

    @property
    def mass(self) -> float:
        """kg; 0 for static bodies."""
        if self.static:
            return 0.0
        if self.physical.mass is not None:
            return self.physical.mass
        return self.physical.density * self.built.volume

    def world_vertices(self) -> np.ndarray:
        return transform_points(self.pose, self.built.vertices)


@dataclass(frozen=True, eq=False)
class Hinge:
    """Body ``moving`` turns about ``axis`` (3,) through ``point`` (3,), world coordinates,
    relative to body ``fixed`` (None: the world)."""

    moving: str
    fixed: str | None
    point: np.ndarray
    axis: np.ndarray


@dataclass(frozen=True, eq=False)
class Scene:
    bodies: dict[str, SceneBody]
    hinges: tuple[Hinge, ...]
    welds: tuple[tuple[str, ...], ...]  # groups of bodies that move as one
    values: np.ndarray  # the real parameter values that made it
    ropes: tuple[SceneRope, ...] = ()

    def jointed_pairs(self) -> set[frozenset[str]]:
        """Pairs of bodies that never collide with each other (joined by a joint)."""
        pairs = {frozenset((h.moving, h.fixed)) for h in self.hinges if h.fixed is not None}
        for group in self.welds:
            pairs.update(frozenset((a, b)) for a in group for b in group if a != b)
        return pairs


def load_parts(scenario: Scenario, build_dir: Store = DEFAULT_BUILD_DIR) -> dict[str, BuiltPart]:
    """The built part of every object that is a part, keyed by object name, built if missing.

    ``build_dir`` is a :class:`~rgmcad.parts.store.PartStore` or a folder (a new store): objects
    of one part share one instance, and so do all the scenarios loaded through one store.
    """
    store = as_store(build_dir)
    return {obj.name: load_part(scenario.family(obj), obj.params, store)
            for obj in scenario.body_objects()}


def make_scene(scenario: Scenario, values, parts: Mapping[str, BuiltPart],
               offsets: Mapping[str, np.ndarray] | None = None) -> Scene:
    """Resolve the layout with real parameter ``values`` (d,) into posed bodies and joints;
    ``offsets`` move objects from their place (:func:`~rgmcad.scene.design_space.world_poses`)."""
    poses = world_poses(scenario, values, offsets)
    bodies: dict[str, SceneBody] = {}
    hinges: list[Hinge] = []
    fixed_parts: list[list[str]] = []
    for obj in scenario.objects.values():
        if obj.part == FRAME:
            continue
        part = parts[obj.name]
        pose = poses[obj.name]
        if part.infinite:
            bodies[obj.name] = SceneBody(obj.name, obj.name, None, pose, obj.physical, True)
            continue
        for key, built in part.bodies.items():
            name = obj.name if key == MAIN else f"{obj.name}.{key}"
            static = obj.physical.static or key != MAIN
            physical = obj.physical if key == MAIN else Physical()
            bodies[name] = SceneBody(name, obj.name, built, pose, physical, static)
        if obj.physical.static and part.joints:  # a static lever: one rigid, fixed body
            fixed_parts.append([_sub(obj.name, key) for key in part.bodies])
            continue
        for joint in part.joints:
            hinges.append(Hinge(
                moving=_sub(obj.name, joint.moving), fixed=_sub(obj.name, joint.fixed),
                point=transform_points(pose, np.asarray([joint.point], float))[0],
                axis=matmul(pose[:3, :3], joint.axis),
            ))
    welds = _weld_groups(scenario)
    for members in fixed_parts:  # into the weld group of its main body, or a group of its own
        group = next((g for g in welds if members[0] in g), None)
        welds = tuple(g for g in welds if g is not group) + (
            (*group, *members[1:]) if group else tuple(members),)
    for joint in scenario.joints:
        if joint.kind == "hinge":
            moving = joint.objects[0]
            fixed = joint.objects[1] if len(joint.objects) > 1 else None
            pose = bodies[moving].pose
            axis = np.asarray(joint.axis, float)
            hinges.append(Hinge(moving, fixed,
                                transform_points(pose, np.asarray([joint.point], float))[0],
                                matmul(pose[:3, :3], axis / norm(axis))))
    return Scene(bodies, tuple(hinges), welds, np.asarray(values, float),
                 scene_ropes(scenario, poses))


def _sub(obj: str, key: str) -> str:
    return obj if key == MAIN else f"{obj}.{key}"


def _weld_groups(scenario: Scenario) -> tuple[tuple[str, ...], ...]:
    """Connected components of the weld joints, in file order, each group's members in the
    file's order of objects (the physics gives a group its first member's surface and damping
    properties)."""
    parent: dict[str, str] = {}

    def find(x):
        while parent.get(x, x) != x:
            x = parent[x]
        return x

    for joint in scenario.joints:
        if joint.kind == "weld":
            a, b = (find(n) for n in joint.objects)
            if a != b:
                parent[b] = a
    groups: dict[str, list[str]] = {}
    for name in parent:
        groups.setdefault(find(name), [])
    for name in list(parent) + list(groups):
        root = find(name)
        if name not in groups[root]:
            groups[root].append(name)
    order = {name: i for i, name in enumerate(scenario.objects)}
    return tuple(tuple(sorted(g, key=order.__getitem__)) for g in groups.values())
