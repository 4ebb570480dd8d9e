"""Rigid transforms: the one place where pose conventions are converted.

Poses in scenario files are ``(x, y, z, heading, pitch, roll)``: metres and degrees, with the
rotation ``R = Rz(heading) @ Rx(pitch) @ Ry(roll)`` (column vectors, right-handed elementary
rotations). This is the convention of the paper's engine (Panda3D's HPR), kept so that the
authors' numbers carry over unchanged: heading turns about +Z, pitch about +X, roll about +Y,
and a positive roll sends +X towards -Z.

Inside rgmcad a pose is a ``(4, 4) float`` homogeneous matrix. pybullet wants positions and
``(x, y, z, w)`` quaternions; :func:`to_pybullet` and :func:`from_pybullet` are the only
conversions.

Everything on the way into the simulator is computed with the functions here
(:func:`matmul`, :func:`norm`, :func:`sin_cos_degrees`, :func:`principal_axes`, ...), never
with numpy's ``@`` (BLAS), LAPACK, or numpy's and the C library's sines and arctangents: those
pick a kernel for the CPU, each kernel rounds the last bit its own way, and contact physics
turns a last-bit difference into another outcome. Additions, multiplications, divisions and
square roots in a fixed order are rounded alike on every CPU, so a layout simulates the same
on every machine (docs/decisions.md, "Simulations that do not depend on the CPU").
"""

from __future__ import annotations

import math

import numpy as np

POSE_KEYS = ("x", "y", "z", "heading", "pitch", "roll")
"""Names of the six pose components, in design-vector order."""

ANGLE_KEYS = frozenset(("heading", "pitch", "roll"))


# Taylor coefficients of sin and cos, enough for a last-bit result on [-pi/4, pi/4]
_SIN = tuple((-1) ** k / math.factorial(2 * k + 1) for k in range(9))
_COS = tuple((-1) ** k / math.factorial(2 * k) for k in range(10))


def _series(x2: np.ndarray, coefficients) -> np.ndarray:
    out = np.full_like(x2, coefficients[-1])
    for c in coefficients[-2::-1]:
        out = out * x2 + c
    return out


def sin_cos_degrees(angles) -> tuple[np.ndarray, np.ndarray]:
    """Sine and cosine of angles in degrees, the same to the last bit on every CPU.

    The angle is reduced exactly in degrees to a multiple of 90 plus at most 45, and only the
    remainder is converted to radians and put through a polynomial: so 90 and 180 degrees
    give exact zeros and ones, and nothing depends on the C library's or numpy's kernels.
    """
    a = np.fmod(np.asarray(angles, dtype=float), 360.0)  # exact
    quarter = np.rint(a / 90.0)
    x = (a - 90.0 * quarter) * (math.pi / 180.0)  # the subtraction is exact
    x2 = x * x
    s, c = x * _series(x2, _SIN), _series(x2, _COS)
    q = quarter.astype(int) % 4
    # + 0.0 turns the -0.0 of an exact quarter turn into 0.0
    return np.choose(q, [s, c, -s, -c]) + 0.0, np.choose(q, [c, -s, -c, s]) + 0.0


_ATAN = tuple((-1) ** k / (2 * k + 1) for k in range(23))  # on |t| <= tan(pi/8)
_EXP = tuple(1 / math.factorial(k) for k in range(15))  # on |r| <= ln(2)/2
# ln 2 in two parts: k * _LN2_HI is exact (its last 32 bits are zeros)
_LN2_HI, _LN2_LO = 0.6931471803691238, 1.9082149292705877e-10


def atan2_degrees(y, x) -> np.ndarray:
    """``atan2(y, x)`` in degrees, in (-180, 180], the same on every CPU (see
    :func:`sin_cos_degrees`): folded to an angle in [0, 45] degrees, then a polynomial."""
    y, x = np.broadcast_arrays(np.asarray(y, dtype=float), np.asarray(x, dtype=float))
    ay, ax = np.abs(y), np.abs(x)
    steep = ay > ax
    big, small = np.where(steep, ay, ax), np.where(steep, ax, ay)
    t = np.divide(small, big, out=np.zeros_like(big), where=big > 0)  # in [0, 1]
    upper = t > 0.41421356237309503  # tan(pi/8): fold (pi/8, pi/4] about pi/4
    t = np.where(upper, (t - 1.0) / (t + 1.0), t)
    deg = np.where(upper, 45.0, 0.0) + t * _series(t * t, _ATAN) * (180.0 / math.pi)
    deg = np.where(steep, 90.0 - deg, deg)
    deg = np.where(np.signbit(x), 180.0 - deg, deg)
    return np.where(np.signbit(y), -deg, deg) + 0.0


def exp(x) -> np.ndarray:
    """``e ** x``, the same on every CPU (see :func:`sin_cos_degrees`)."""
    x = np.asarray(x, dtype=float)
    k = np.rint(x / math.log(2.0))
    r = (x - k * _LN2_HI) - k * _LN2_LO
    return np.ldexp(_series(r, _EXP), k.astype(int))


_ONE_PRODUCT = {(2, 2): "ij,jk->ik", (2, 1): "ij,j->i", (1, 2): "j,jk->k"}


def matmul(a, b) -> np.ndarray:
    """``a @ b`` the same on every CPU (see the module's docstring): shapes (..., n, k) @
    (..., k, m), (..., n, k) @ (k,) and (k,) @ (k, m).

    One product goes through ``np.einsum`` (without ``optimize`` it runs numpy's own loops,
    compiled once for the baseline instruction set, never BLAS; 3 us for 4 x 4 against 10 us
    written out); a stack of them is summed term by term, faster there.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    subscripts = _ONE_PRODUCT.get((a.ndim, b.ndim))
    if subscripts is not None:
        return np.einsum(subscripts, a, b)
    if b.ndim == 1:
        return dot(a, b)
    if a.ndim == 1:
        return matmul(a[None], b)[..., 0, :]
    out = a[..., :, 0:1] * b[..., 0:1, :]
    for j in range(1, a.shape[-1]):
        out = out + a[..., :, j:j + 1] * b[..., j:j + 1, :]
    return out


def dot(u, v) -> np.ndarray:
    """Sum of ``u * v`` over the last axis, in a fixed order (``np.dot`` calls BLAS)."""
    terms = np.asarray(u, dtype=float) * np.asarray(v, dtype=float)
    out = terms[..., 0]
    for j in range(1, terms.shape[-1]):
        out = out + terms[..., j]
    return out


def norm(v) -> np.ndarray:
    """Euclidean length over the last axis, the same on every CPU."""
    return np.sqrt(dot(v, v))


def principal_axes(symmetric) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (3,), ascending, and a right-handed rotation (3, 3) whose columns are the
    eigenvectors of a symmetric 3 x 3 matrix (its symmetric part).

    Jacobi rotations in plain floats, the same on every CPU, where LAPACK's ``eigh`` is not;
    an axis-aligned matrix keeps its axes, equal eigenvalues keep their axes' order, and each
    axis has its largest component positive (then the third turns for a right hand).
    """
    m = np.asarray(symmetric, dtype=float)
    a = [[0.5 * (float(m[i, j]) + float(m[j, i])) for j in range(3)]
         for i in range(3)]
    v = [[1.0 if i == j else 0.0 for j in range(3)] for i in range(3)]
    for _ in range(50):
        if a[0][1] == a[0][2] == a[1][2] == 0.0:
            break
        for p, q in ((0, 1), (0, 2), (1, 2)):
            _rotate(a, v, p, q)
    order = sorted(range(3), key=lambda k: a[k][k])  # stable: equal moments keep their axes
    moments = np.array([a[k][k] for k in order])
    axes = np.array([[v[i][k] for k in order] for i in range(3)])
    for k in range(3):  # the sign of each axis: its largest component positive
        if axes[int(np.argmax(np.abs(axes[:, k]))), k] < 0:
            axes[:, k] = -axes[:, k]
    x, y, z = axes.T
    if x[0] * (y[1] * z[2] - y[2] * z[1]) - x[1] * (y[0] * z[2] - y[2] * z[0]) \
            + x[2] * (y[0] * z[1] - y[1] * z[0]) < 0:
        axes[:, 2] = -axes[:, 2]
    return moments, axes


def _rotate(a: list[list[float]], v: list[list[float]], p: int, q: int) -> None:
    """One Jacobi rotation zeroing ``a[p][q]`` of the symmetric 3 x 3 ``a``; ``v`` gathers the
    rotations (its columns become the eigenvectors)."""
    apq = a[p][q]
    if apq == 0.0:
        return
    g = 100.0 * abs(apq)
    if abs(a[p][p]) + g == abs(a[p][p]) and abs(a[q][q]) + g == abs(a[q][q]):
        a[p][q] = a[q][p] = 0.0  # below the diagonal's last bit
        return
    theta = (a[q][q] - a[p][p]) / (2.0 * apq)
    if abs(theta) > 1e150:
        t = 0.5 / theta
    else:
        t = math.copysign(1.0, theta) / (abs(theta) + math.sqrt(theta * theta + 1.0))
    c = 1.0 / math.sqrt(t * t + 1.0)
    s = t * c
    a[p][p] -= t * apq
    a[q][q] += t * apq
    a[p][q] = a[q][p] = 0.0
    r = 3 - p - q
    arp, arq = a[r][p], a[r][q]
    a[r][p] = a[p][r] = c * arp - s * arq
    a[r][q] = a[q][r] = s * arp + c * arq
    for row in v:
        vp, vq = row[p], row[q]
        row[p], row[q] = c * vp - s * vq, s * vp + c * vq


def rotation_hpr(heading_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    """(3, 3) rotation ``Rz(h) @ Rx(p) @ Ry(r)`` from angles in degrees (written out: every
    object of every layout goes through here)."""
    (sh, sp, sr), (ch, cp, cr) = sin_cos_degrees([heading_deg, pitch_deg, roll_deg])
    return np.array([
        [ch * cr - sh * sp * sr, -sh * cp, ch * sr + sh * sp * cr],
        [sh * cr + ch * sp * sr, ch * cp, sh * sr - ch * sp * cr],
        [-cp * sr, sp, cp * cr],
    ])


def rotation_2d(angle_deg: float) -> np.ndarray:
    """(2, 2) rotation of the plane by ``angle_deg`` degrees, counter-clockwise."""
    s, c = sin_cos_degrees(angle_deg)
    return np.array([[c, -s], [s, c]])


def pose_matrices(poses6: np.ndarray) -> np.ndarray:
    """(n, 4, 4) matrices of n poses ``(x, y, z, heading, pitch, roll)`` (n, 6): the
    vectorised :func:`pose_matrix` (validity tests thousands of layouts at once)."""
    poses6 = np.asarray(poses6, dtype=float)
    (sh, sp, sr), (ch, cp, cr) = sin_cos_degrees(poses6[:, 3:].T)
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
    """(3,) heading, pitch, roll in degrees of a (3, 3) rotation (inverse of rotation_hpr);
    pitch in [-90, 90]. At pitch +-90 only heading and roll's sum is defined: roll is 0."""
    m = np.asarray(rotation, dtype=float)
    cos_pitch = np.sqrt(m[0, 1] * m[0, 1] + m[1, 1] * m[1, 1])
    pitch = atan2_degrees(m[2, 1], cos_pitch)
    if cos_pitch < 1e-12:
        return np.array([float(atan2_degrees(m[1, 0], m[0, 0])), float(pitch), 0.0])
    return np.array([float(atan2_degrees(-m[0, 1], m[1, 1])), float(pitch),
                     float(atan2_degrees(-m[2, 0], m[2, 2]))])


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
    out[:3, 3] = -matmul(rt, matrix[:3, 3])
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
    return m[:3, 3].tolist(), (quat / norm(quat)).tolist()


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
    return matmul(points, matrix[:3, :3].T) + matrix[:3, 3]
