"""The design space: free layout parameters <-> poses.

A layout is a vector ``v`` in ``[0, 1]^d``; free parameter ``i`` takes the real value
``low_i + v_i (high_i - low_i)`` (metres or degrees). Real values outside the ranges are
allowed (the authors' own initial layouts leave them), and map to vectors outside the cube.
World poses compose parent-relative poses down the scene graph.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from rgmcad.geometry import POSE_KEYS, matmul, pose_matrices
from rgmcad.scene.model import Scenario


def bounds(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """(d,) lows and (d,) highs of the free parameters, real units."""
    low = np.array([f.low for f in scenario.free], float)
    high = np.array([f.high for f in scenario.free], float)
    return low, high


def values_from_vector(scenario: Scenario, vector) -> np.ndarray:
    """Real parameter values (d,) of a normalised vector (d,)."""
    vector = np.asarray(vector, float)
    if vector.shape != (scenario.dimension,):
        raise ValueError(f"expected a vector of {scenario.dimension} values, got {vector.shape}")
    low, high = bounds(scenario)
    return low + vector * (high - low)


def vector_from_values(scenario: Scenario, values) -> np.ndarray:
    """Normalised vector (d,) of real parameter values (d,) (may leave [0, 1])."""
    values = np.asarray(values, float)
    low, high = bounds(scenario)
    return (values - low) / (high - low)


def values_from_mapping(scenario: Scenario, mapping: Mapping[str, float]) -> np.ndarray:
    """(d,) real values from ``{"object.component": value}``; missing ones keep the file's."""
    initial = scenario.layouts["initial"]
    return np.array([float(mapping.get(f.name, initial[f.name])) for f in scenario.free])


def local_poses(scenario: Scenario, values) -> dict[str, tuple[float, ...]]:
    """Every object's parent-relative pose with the free components set to ``values``."""
    poses = {name: list(obj.pose) for name, obj in scenario.objects.items()}
    for f, v in zip(scenario.free, np.asarray(values, float), strict=True):
        poses[f.object][POSE_KEYS.index(f.component)] = float(v)
    return {k: tuple(v) for k, v in poses.items()}


def world_poses(scenario: Scenario, values, offsets: Mapping[str, np.ndarray] | None = None
                ) -> dict[str, np.ndarray]:
    """(4, 4) world transform of every object (frames included) for real ``values`` (d,):
    :func:`world_poses_many` of one layout (bit for bit what it gives that layout among
    many, so validity and simulation see the same poses)."""
    values = np.asarray(values, float)
    if values.shape != (scenario.dimension,):
        raise ValueError(f"expected {scenario.dimension} values, got {values.shape}")
    return {name: poses[0]
            for name, poses in world_poses_many(scenario, values[None], offsets).items()}


def world_poses_many(scenario: Scenario, values, offsets: Mapping[str, np.ndarray] | None = None
                     ) -> dict[str, np.ndarray]:
    """(n, 4, 4) world transforms of every object (frames included) for n layouts of real
    ``values`` (n, d); children compose their parent-relative pose onto their parent's.
    ``offsets``: ``{object: (6,)}`` added to those objects' parent-relative poses (x, y, z,
    heading, pitch, roll) after the free values are set (where a hand put them)."""
    values = np.atleast_2d(np.asarray(values, float))
    row = {name: i for i, name in enumerate(scenario.objects)}
    # every object's local pose in every layout, made in one vectorised call
    local6 = np.repeat(np.array([obj.pose for obj in scenario.objects.values()], float)[:, None],
                       len(values), axis=1)
    for i, f in enumerate(scenario.free):
        local6[row[f.object], :, POSE_KEYS.index(f.component)] = values[:, i]
    for name, offset in (offsets or {}).items():
        local6[row[name]] += np.asarray(offset, float)
    local = pose_matrices(local6.reshape(-1, 6)).reshape(len(row), len(values), 4, 4)
    world: dict[str, np.ndarray] = {}

    def resolve(name):
        if name not in world:
            parent = scenario.objects[name].parent
            world[name] = (local[row[name]] if parent is None
                           else matmul(resolve(parent), local[row[name]]))
        return world[name]

    for name in scenario.objects:
        resolve(name)
    return world
