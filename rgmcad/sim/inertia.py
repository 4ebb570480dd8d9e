"""Mass properties of rigid bodies from their CAD solids (pybullet would derive them from
the collision shapes' bounding boxes).

Each body's part gives its centre of mass, volume and inertia per unit density; the body's
mass scales them. Bodies welded into one rigid body combine by the parallel axis theorem;
pybullet takes the result as a mass, an inertial frame on the principal axes and the three
principal moments.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rgmcad.geometry import dot, matmul, principal_axes
from rgmcad.scene.bodies import SceneBody


@dataclass(frozen=True)
class _Mass:
    mass: float
    com: np.ndarray  # (3,) in the body frame
    inertia: np.ndarray  # (3, 3) about com, body frame axes


def _mass_of(bodies: list[tuple[SceneBody, np.ndarray]]) -> _Mass:
    """Combined mass properties of bodies given with their (4, 4) pose in a common frame."""
    total, moment = 0.0, np.zeros(3)
    parts = []
    for body, pose in bodies:
        m = body.mass
        if m <= 0:
            continue
        rot = pose[:3, :3]
        com = matmul(rot, body.built.centre_of_mass) + pose[:3, 3]
        inertia = matmul(matmul(rot, body.built.inertia_unit * (m / body.built.volume)), rot.T)
        parts.append((m, com, inertia))
        total += m
        moment += m * com
    com = moment / total if total > 0 else np.zeros(3)  # all static: the frame's origin
    inertia = np.zeros((3, 3))
    for m, c, i in parts:
        d = c - com
        inertia += i + m * (dot(d, d) * np.eye(3) - np.outer(d, d))  # parallel axis theorem
    return _Mass(total, com, inertia)


def _principal(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (3,) and a right-handed rotation (3, 3) whose columns are the axes
    (see :func:`~rgmcad.geometry.principal_axes`: LAPACK's ``eigh`` differs across CPUs in the
    last bits and, where two moments are equal, in which axes it returns at all; the inertial
    frame is the frame pybullet simulates the body in)."""
    moments, axes = principal_axes(inertia)
    return np.maximum(moments, 1e-12), axes


def inertial_frame(bodies: list[tuple[SceneBody, np.ndarray]]):
    """(mass, (4, 4) principal inertial frame, (3,) principal moments) of bodies given with
    their pose in a common frame."""
    props = _mass_of(bodies)
    moments, axes = _principal(props.inertia)
    com_frame = np.eye(4)
    com_frame[:3, :3], com_frame[:3, 3] = axes, props.com
    return props.mass, com_frame, moments
