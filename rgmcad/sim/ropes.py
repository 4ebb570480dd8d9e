"""Ropes in the physics world: inextensible, free to go slack, pulling only along themselves.

A rope is one unilateral constraint on its path length ``s`` (first end, fixed pulley points,
second end): ``s <= L``. Before every physics step :class:`RopeSolver` predicts the velocity
each end's body would have after the step under gravity alone, and finds the tension impulse
``lambda >= 0`` that keeps the path from outgrowing the rope within the step:

* ``J v`` is the rate of change of ``s``: the sum over the two ends of the end's velocity
  along its last segment (pulleys are fixed, so the rope slides over them without friction and
  both sides share one length: an Atwood machine);
* slack by ``c = L - s > 0``: the ends may close that gap in this step (``J v <= c / dt``), so
  a slack rope pulls with exactly zero force until the step it would go taut;
* stretched by ``-c > 0`` (from contacts or rounding): pulled back by a fraction
  :data:`STRETCH_RECOVERY` of it per step;
* ``lambda = max(0, (J v_pred - allowed) / K)`` with ``K = J M^-1 J^T``, the rope's effective
  inverse mass: ``1/m + |I^-1/2 (r x n)|^2`` for a free body, ``(a . r x n)^2 / I_a`` for a
  body turning on a hinge of axis ``a``. Ropes sharing a body are solved together by a few
  projected Gauss-Seidel sweeps.

The impulse enters the step as an external force ``lambda / dt`` at each end along its
segment, so pybullet's own solver then sees it together with contacts and joints. With no
contacts this is exact: an Atwood machine falls at ``(m2 - m1) / (m1 + m2) g`` (tests in
tests/test_ropes.py). The authors instead rewrote slider limits every step and moved the
heavier side at a constant speed; nothing of that here. Pulleys are points: a wheel's radius
and inertia are not part of the rope (a pulley part is scenery, or a body of its own).
"""

from __future__ import annotations

import math

from rgmcad.geometry import matmul
from rgmcad.scene.bodies import Scene
from rgmcad.sim.engine import pb

STRETCH_RECOVERY = 0.3
"""Fraction of a rope's stretch corrected per step (a Baumgarte factor)."""
SWEEPS = 4
"""Gauss-Seidel sweeps when ropes share a body (one rope alone is solved exactly in one)."""


def _rotate(q, v):
    """Vector ``v`` (3,) rotated by the quaternion ``q`` (x, y, z, w)."""
    qx, qy, qz, qw = q
    vx, vy, vz = v
    tx, ty, tz = 2 * (qy * vz - qz * vy), 2 * (qz * vx - qx * vz), 2 * (qx * vy - qy * vx)
    return (vx + qw * tx + qy * tz - qz * ty, vy + qw * ty + qz * tx - qx * tz,
            vz + qw * tz + qx * ty - qy * tx)


def _unrotate(q, v):
    return _rotate((-q[0], -q[1], -q[2], q[3]), v)


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


class _Free:
    """A free rigid body: state (vx, vy, vz, wx, wy, wz) of its centre of mass."""

    def __init__(self, uid, cid, gravity):
        info = pb.getDynamicsInfo(uid, -1, physicsClientId=cid)
        self.uid, self.link, self.cid, self.gravity = uid, -1, cid, gravity
        self.inv_mass = 1.0 / info[0]
        self.inv_inertia = tuple(1.0 / i if i > 0 else 0.0 for i in info[2])

    def read(self, dt):
        cid = self.cid
        self.pos, self.orn = pb.getBasePositionAndOrientation(self.uid, physicsClientId=cid)
        v, w = pb.getBaseVelocity(self.uid, physicsClientId=cid)
        self.v = [v[0], v[1], v[2] - self.gravity * dt, w[0], w[1], w[2]]

    def hook(self, local):
        """(hook point in the world, its lever arm r) for a hook ``local`` (COM frame)."""
        r = _rotate(self.orn, local)
        hook = (self.pos[0] + r[0], self.pos[1] + r[1], self.pos[2] + r[2])
        return hook, r

    def jacobian(self, r, n):
        """(J row, J M^-1 J^T) of a pull along -n with lever arm r."""
        rn = _cross(r, n)
        b = _unrotate(self.orn, rn)
        ii = self.inv_inertia
        k = self.inv_mass + b[0] * b[0] * ii[0] + b[1] * b[1] * ii[1] + b[2] * b[2] * ii[2]
        return (n, rn, b), k

    def rate(self, jac):
        (n, rn, _), v = jac, self.v
        return n[0] * v[0] + n[1] * v[1] + n[2] * v[2] + rn[0] * v[3] + rn[1] * v[4] + rn[2] * v[5]

    def push(self, jac, impulse):
        """Apply ``impulse`` along -J to the predicted state."""
        (n, _, b), v = jac, self.v  # b: the lever arm's moment in the body frame
        s = -impulse * self.inv_mass
        v[0] += s * n[0]
        v[1] += s * n[1]
        v[2] += s * n[2]
        ii = self.inv_inertia
        dw = _rotate(self.orn, (-impulse * b[0] * ii[0], -impulse * b[1] * ii[1],
                                -impulse * b[2] * ii[2]))
        v[3] += dw[0]
        v[4] += dw[1]
        v[5] += dw[2]


class _Hinged:
    """A body turning on a hinge about a fixed axle: state (angular rate about the axis,)."""

    def __init__(self, uid, cid, gravity, point, axis):
        info = pb.getDynamicsInfo(uid, 0, physicsClientId=cid)
        self.uid, self.link, self.cid, self.gravity = uid, 0, cid, gravity
        self.mass = info[0]
        self.point = tuple(float(x) for x in point)
        norm = math.sqrt(_dot(axis, axis))
        self.axis = tuple(float(x) / norm for x in axis)
        pos, orn = pb.getLinkState(uid, 0, physicsClientId=cid)[:2]
        a_local = _unrotate(orn, self.axis)
        arm = _cross(self.axis, tuple(pos[i] - self.point[i] for i in range(3)))
        # moment of inertia about the axis: constant, the body turns about that very axis
        self.inertia = (sum(a_local[i] ** 2 * info[2][i] for i in range(3))
                        + self.mass * _dot(arm, arm))

    def read(self, dt):
        state = pb.getLinkState(self.uid, 0, computeLinkVelocity=1, computeForwardKinematics=1,
                               physicsClientId=self.cid)
        self.pos, self.orn = state[0], state[1]
        a, p, c = self.axis, self.point, state[0]
        # gravity's torque about the axis: a . ((com - p) x (0, 0, -m g))
        torque = -self.mass * self.gravity * (a[0] * (c[1] - p[1]) - a[1] * (c[0] - p[0]))
        self.v = [_dot(state[7], a) + torque / self.inertia * dt]

    def hook(self, local):
        r = _rotate(self.orn, local)
        hook = (self.pos[0] + r[0], self.pos[1] + r[1], self.pos[2] + r[2])
        return hook, (hook[0] - self.point[0], hook[1] - self.point[1], hook[2] - self.point[2])

    def jacobian(self, r, n):
        j = _dot(self.axis, _cross(r, n))
        return j, j * j / self.inertia

    def rate(self, jac):
        return jac * self.v[0]

    def push(self, jac, impulse):
        self.v[0] -= impulse * jac / self.inertia


class RopeSolver:
    """Applies the ropes' tension before each step of ``world`` (call it, then step)."""

    def __init__(self, world, scene: Scene):
        cid, gravity = world.cid, world.settings.gravity
        self.apply = pb.applyExternalForce
        self.cid, self.dt = cid, world.settings.timestep
        hinge_of = {}
        for h in scene.hinges:
            handle = world.handles[h.moving]
            hinge_of[(handle.uid, handle.link)] = h
        bodies = {}
        self.ropes = []
        for rope in scene.ropes:
            ends = []
            for body, local, fixed in zip(rope.bodies, rope.local,
                                          (rope.points[0], rope.points[-1]), strict=True):
                if body is None:
                    ends.append((None, tuple(float(x) for x in fixed)))
                    continue
                handle = world.handles[body]
                key = (handle.uid, handle.link)
                if key not in bodies:
                    if handle.link < 0:
                        bodies[key] = _Free(handle.uid, cid, gravity)
                    else:
                        h = hinge_of[key]
                        bodies[key] = _Hinged(handle.uid, cid, gravity, h.point, h.axis)
                at = matmul(handle.com_to_part[:3, :3], local) + handle.com_to_part[:3, 3]
                ends.append((bodies[key], tuple(float(x) for x in at)))
            pulleys = [tuple(float(x) for x in p) for p in rope.points[1:-1]]
            middle = sum(math.dist(a, b) for a, b in zip(pulleys[:-1], pulleys[1:], strict=True))
            self.ropes.append((ends, pulleys, rope.length - middle))
        self.bodies = list(bodies.values())
        self.sweeps = 1 if self._independent() else SWEEPS

    def _independent(self) -> bool:
        seen = set()
        for ends, _, _ in self.ropes:
            for body, _ in ends:
                if body is not None:
                    if id(body) in seen:
                        return False
                    seen.add(id(body))
        return True

    def __call__(self) -> None:
        dt = self.dt
        for body in self.bodies:
            body.read(dt)
        rows = []
        for ends, pulleys, free_length in self.ropes:
            hooks, segments = [], []
            for body, at in ends:
                hooks.append((None, at, None) if body is None else (body, *body.hook(at)))
            # each end's neighbour on the path: a pulley, or the other end
            anchors = (pulleys[0] if pulleys else hooks[1][1],
                       pulleys[-1] if pulleys else hooks[0][1])
            active = []
            for (body, hook, r), anchor in zip(hooks, anchors, strict=True):
                d = (hook[0] - anchor[0], hook[1] - anchor[1], hook[2] - anchor[2])
                dist = math.sqrt(_dot(d, d))
                segments.append(dist)
                if body is not None and dist > 1e-9:
                    n = (d[0] / dist, d[1] / dist, d[2] / dist)
                    active.append((body, hook, n, *body.jacobian(r, n)))
            s = segments[0] if not pulleys else segments[0] + segments[1]
            gap = free_length - s
            allowed = gap / dt if gap > 0 else STRETCH_RECOVERY * gap / dt
            k = sum(a[4] for a in active)
            if k > 0:
                rows.append([active, allowed, k, 0.0])
        for _ in range(self.sweeps):
            for row in rows:
                active, allowed, k, total = row
                rate = sum(body.rate(jac) for body, _, _, jac, _ in active)
                new = max(0.0, total + (rate - allowed) / k)
                if new != total:
                    for body, _, _, jac, _ in active:
                        body.push(jac, new - total)
                    row[3] = new
        apply, cid, world_frame = self.apply, self.cid, pb.WORLD_FRAME
        for active, _, _, total in rows:
            if total > 0:
                f = total / dt
                for body, hook, n, _, _ in active:
                    apply(body.uid, body.link, (-f * n[0], -f * n[1], -f * n[2]), hook,
                          world_frame, physicsClientId=cid)


def with_ropes(world, scene: Scene, step):
    """``step`` preceded by the ropes' tension (``step`` itself when there are no ropes)."""
    if not scene.ropes:
        return step
    solve = RopeSolver(world, scene)

    def step_with_ropes():
        solve()
        step()

    return step_with_ropes
