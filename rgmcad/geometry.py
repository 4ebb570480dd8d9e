"""Rigid transforms: the one place where pose conventions are converted.

Poses in scenario files are ``(x, y, z, heading, pitch, roll)``: metres and degrees, with the
rotation ``R = Rz(heading) @ Rx(pitch) @ Ry(roll)`` (column vectors, right-handed elementary
rotations). This is the convention of the paper's engine (Panda3D's HPR), kept so that the
authors' numbers carry over unchanged: heading turns about +Z, pitch about +X, roll about +Y,
and a positive roll sends +X towards -Z.

Inside rgmcad a pose is a ``(4, 4) float`` homogeneous matrix. pybullet wants positions and
``(x, y, z, w)`` quaternions; :func:`to_pybullet` and :func:`from_pybullet` are the only
conversions.
"""

from __future__ import annotations

import numpy as np

POSE_KEYS = ("x", "y", "z", "heading", "pitch", "roll")
"""Names of the six pose components, in design-vector order."""

ANGLE_KEYS = frozenset(("heading", "pitch", "roll"))


def rotation_hpr(heading_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """(3, 3) rotation ``Rz(h) @ Rx(p) @ Ry(r)`` from angles in degrees (written out: every
    object of every layout goes through here)."""
    h, p, r = np.radians([heading_deg, pitch_deg, roll_deg])
    ch, sh, cp, sp, cr, sr = np.cos(h), np.sin(h), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    return np.array([
        [ch * cr - sh * sp * sr, -sh * cp, ch * sr + sh * sp * cr],
        [sh * cr + ch * sp * sr, ch * cp, sh * sr - ch * sp * cr],
        [-cp * sr, sp, cp * cr],
    ])


def rotation_2d(angle_deg: float) -> np.ndarray:
    """(2, 2) rotation of the plane by ``angle_deg`` degrees, counter-clockwise."""
    a = np.radians(angle_deg)
    return np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])


def pose_matrices(poses6: np.ndarray) -> np.ndarray:
    """(n, 4, 4) matrices of n poses ``(x, y, z, heading, pitch, roll)`` (n, 6): the
    vectorised :func:`pose_matrix` (validity tests thousands of layouts at once)."""
    poses6 = np.asarray(poses6, dtype=float)
    h, p, r = np.radians(poses6[:, 3:]).T
    ch, sh, cp, sp, cr, sr = np.cos(h), np.sin(h), np.cos(p), np.sin(p), np.cos(r), np.sin(r)
    m = np.zeros((len(poses6), 4, 4))
    m[:, 0, 0] = ch * cr - sh * sp * sr
    m[:, 0, 1] = -sh * cp
    m[:, 0, 2] = ch * sr + sh * sp * cr
    m[:, 1, 0] = sh * cr + ch * sp * sr
    m[:, 1, 1] = ch * cp
    m[:, 1, 2] = sh * sr - ch * sp * cr
    m[:, 2, 0] = -cp * sr
    m[:, 2, 1] = sp
    m[:, 2, 2] = cp * cr
    m[:, :3, 3] = poses6[:, :3]
    m[:, 3, 3] = 1.0
    return m


def hpr_of(rotation: np.ndarray) -> np.ndarray:
    """(3,) heading, pitch, roll in degrees of a (3, 3) rotation (inverse of rotation_hpr)."""
    from scipy.spatial.transform import Rotation  # here: part family files import this module

    return Rotation.from_matrix(rotation).as_euler("ZXY", degrees=True)


def pose_matrix(pose6) -> np.ndarray:
    """(4, 4) matrix of a pose ``(x, y, z, heading, pitch, roll)`` in metres and degrees."""
    x, y, z, h, p, r = (float(v) for v in pose6)
    m = np.eye(4)
    m[:3, :3] = rotation_hpr(h, p, r)
    m[:3, 3] = (x, y, z)
    return m


def pose6_of(matrix: np.ndarray) -> np.ndarray:
    """(6,) ``(x, y, z, heading, pitch, roll)`` of a (4, 4) rigid transform."""
    return np.concatenate([matrix[:3, 3], hpr_of(matrix[:3, :3])])


def translation(offset) -> np.ndarray:
    """(4, 4) transform that moves points by ``offset`` (3,), metres."""
    m = np.eye(4)
    m[:3, 3] = offset
    return m


def invert(matrix: np.ndarray) -> np.ndarray:
    """Inverse of a (4, 4) rigid transform."""
    out = np.eye(4)
    rt = matrix[:3, :3].T
    out[:3, :3] = rt
    out[:3, 3] = -rt @ matrix[:3, 3]
    return out


def to_pybullet(matrix: np.ndarray) -> tuple[list[float], list[float]]:
    """Position and unit (x, y, z, w) quaternion of a (4, 4) rigid transform, for pybullet.

    Shepperd's method, written out: scipy's conversion costs ~50 us, and world building calls
    this for every body.
    """
    m = matrix
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s]
    quat = np.asarray(q, float)
    return m[:3, 3].tolist(), (quat / np.linalg.norm(quat)).tolist()


def from_pybullet(position, quaternion) -> np.ndarray:
    """(4, 4) rigid transform from a pybullet position and unit (x, y, z, w) quaternion.

    Written out rather than through scipy: it runs for awake events at every step.
    """
    x, y, z, w = quaternion
    px, py, pz = position
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), px],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), py],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), pz],
        [0.0, 0.0, 0.0, 1.0],
    ])


def rotated_z(quaternion, vector) -> float:
    """World z of ``vector`` (3 floats) rotated by a pybullet (x, y, z, w) quaternion: the third
    row of :func:`from_pybullet`'s rotation times the vector. Plain floats, for per-step
    readers."""
    x, y, z, w = quaternion
    a, b, c = vector
    return (2 * (x * z - y * w) * a + 2 * (y * z + x * w) * b
            + (1 - 2 * (x * x + y * y)) * c)


def moved_point(position, quaternion, point) -> tuple[float, float, float]:
    """``point`` (3 floats) moved by a pybullet position and (x, y, z, w) quaternion, as
    :func:`from_pybullet`'s transform would move it. Plain floats, for per-step readers."""
    px, py, pz = position
    x, y, z, w = quaternion
    a, b, c = point
    return (px + (1 - 2 * (y * y + z * z)) * a + 2 * (x * y - z * w) * b
            + 2 * (x * z + y * w) * c,
            py + 2 * (x * y + z * w) * a + (1 - 2 * (x * x + z * z)) * b
            + 2 * (y * z - x * w) * c,
            pz + 2 * (x * z - y * w) * a + 2 * (y * z + x * w) * b
            + (1 - 2 * (x * x + y * y)) * c)


def point_in_frame(position, quaternion, point) -> tuple[float, float, float]:
    """A world ``point`` (3 floats) in the frame at a pybullet position and (x, y, z, w)
    quaternion: the inverse of :func:`moved_point`. Plain floats, for per-step readers."""
    px, py, pz = point
    x, y, z, w = quaternion
    dx, dy, dz = px - position[0], py - position[1], pz - position[2]
    return ((1 - 2 * (y * y + z * z)) * dx + 2 * (x * y + z * w) * dy + 2 * (x * z - y * w) * dz,
            2 * (x * y - z * w) * dx + (1 - 2 * (x * x + z * z)) * dy + 2 * (y * z + x * w) * dz,
            2 * (x * z + y * w) * dx + 2 * (y * z - x * w) * dy + (1 - 2 * (x * x + y * y)) * dz)


def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a (4, 4) transform to (n, 3) points."""
    return points @ matrix[:3, :3].T + matrix[:3, 3]
