"""The pybullet view of a scene: a world built from a :class:`~rgmcad.scene.bodies.Scene`.

A world lives in an :class:`~rgmcad.sim.engine.Engine` (its own pybullet client, or one a
caller hands it to reuse); it resets the engine and rebuilds from scratch, because restoring
a saved state does not reproduce a fresh run (stale contact caches). Close it with
:meth:`World.close` or ``with World(...) as world:``. Engine workarounds, all in this module
and :mod:`rgmcad.sim.shapes`:

* free bodies use maximal coordinates: pybullet's default multibodies add damping and ignore
  continuous collision detection (CCD);
* a hinge is a two-link multibody (fixed base = the axle or the world, revolute link = the
  moving body) whose default velocity motor is switched off; ``createConstraint`` has no hinge
  (bullet3 issues #2005, #4701);
* collision shapes are built by :func:`~rgmcad.sim.shapes.collision_shape`: OBJ files for
  compounds (bullet3#2185), the settings' collision margin on every piece of every kind of
  body, hulls inset by it so that the surface the physics sees is the part's;
* sleeping is disabled, so slow levers are never frozen;
* inertia comes from the CAD solid (principal moments and axes), not from the collision
  shape's bounding box.

Positions and orientations are read as (4, 4) transforms of each body's *part frame*.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from rgmcad.geometry import from_pybullet, invert, matmul, moved_point, norm, rotated_z, to_pybullet
from rgmcad.parts.pieces import Piece, PlanePiece
from rgmcad.scene.bodies import Scene, SceneBody
from rgmcad.scene.model import SimulationSettings
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine, pb
from rgmcad.sim.inertia import inertial_frame
from rgmcad.sim.ropes import with_ropes
from rgmcad.sim.shapes import collision_shape


@dataclass(frozen=True)
class Handle:
    """Where a scene body lives in pybullet: body id, link index (-1: base), and the
    (4, 4) transform from the link's centre-of-mass frame to the part frame."""

    uid: int
    link: int
    com_to_part: np.ndarray


def _closed() -> None:
    raise RuntimeError("this world is closed")


class World:
    """A pybullet world built from a scene, in an engine it holds while it is open.

    Parameters
    ----------
    scene : the posed bodies and joints.
    settings : every engine parameter (time step, solver, CCD).
    engine : where to build; None: an engine of its own, closed with the world. A given
        engine is reset, and must hold no other open world.
    cache : data derived from the parts (OBJ files, mass properties, hulls), kept by the
        caller across worlds; None: one of its own.
    """

    def __init__(self, scene: Scene, settings: SimulationSettings, engine: Engine | None = None,
                 cache: PartCache | None = None):
        self.scene = scene
        self.settings = settings
        self.closed = False
        self._own_engine, self._own_cache = engine is None, cache is None
        # a world's own engine only simulates: no renderer (pictures have engines of their own)
        self.engine = e = Engine(renderer=False) if engine is None else engine
        self.cache = PartCache() if cache is None else cache
        e.hold(self)
        self.cid = e.cid
        self.time = 0.0
        try:
            e.resetSimulation()
            e.setGravity(0, 0, -settings.gravity)
            e.setPhysicsEngineParameter(
                fixedTimeStep=settings.timestep,
                numSubSteps=0,
                numSolverIterations=settings.solver_iterations,
                erp=settings.erp,
                contactERP=settings.contact_erp,
                frictionERP=settings.friction_erp,
                useSplitImpulse=int(settings.split_impulse),
                contactBreakingThreshold=settings.contact_breaking_threshold,
                restitutionVelocityThreshold=settings.restitution_velocity_threshold,
                enableConeFriction=0,
                deterministicOverlappingPairs=1,
                enableSAT=0,
                enableFileCaching=1,
                solverResidualThreshold=settings.solver_residual_threshold,
            )
            self.handles: dict[str, Handle] = {}
            self._build()
        except BaseException:
            self.close()
            raise
        # positional client id: cheaper; ropes pull before each step
        self._step = with_ropes(self, scene, functools.partial(pb.stepSimulation, self.cid))
        self._dt = settings.timestep

    def close(self) -> None:
        """Release the engine (closing it if it is the world's own); idempotent."""
        if self.closed:
            return
        self.closed = True
        self._step = _closed
        if self._own_engine:
            self.engine.close()
        else:
            self.engine.release(self)
        if self._own_cache:
            self.cache.close()

    def __enter__(self) -> World:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # -- construction ----------------------------------------------------------------------

    def _shape(self, pieces: list[tuple[Piece, np.ndarray]]) -> int:
        """A collision shape from pieces given with their (4, 4) frame in the shape frame."""
        return collision_shape(self.engine, pieces, self.cache, self.settings.convex_margin)

    def _build(self):
        scene = self.scene
        welded = {name: group for group in scene.welds for name in group}
        hinged = {h.moving: h for h in scene.hinges}
        hinge_bases = {h.fixed for h in scene.hinges if h.fixed is not None}
        done: set[str] = set()
        free: list[list[SceneBody]] = []
        for name in scene.bodies:
            if name in done:
                continue
            group = welded.get(name, (name,))
            members = [scene.bodies[n] for n in group]
            done.update(group)
            moving_hinge = next((hinged[n] for n in group if n in hinged), None)
            if moving_hinge is not None:
                self._build_hinged(members, moving_hinge)
            elif not any(n in hinge_bases for n in group):  # bases go with their hinge
                free.append(members)
        # Identical single bodies (the dominoes of a run) are created in one batch call, at
        # a tenth of the cost per body of separate calls.
        batches: dict[tuple, list[SceneBody]] = {}
        for members in free:
            if len(members) == 1 and not members[0].plane:
                batches.setdefault(self._batch_key(members[0]), []).append(members[0])
        for members in free:
            if len(members) == 1 and not members[0].plane:
                batch = batches.pop(self._batch_key(members[0]), None)
                if batch is not None:
                    self._build_batch(batch)
            else:
                self._build_free(members)
        for h in scene.hinges:
            if h.fixed is not None and h.fixed not in self.handles:
                raise ValueError(f"hinge base {h.fixed!r} was not built")

    @staticmethod
    def _batch_key(body: SceneBody) -> tuple:
        return (id(body.built), body.physical, body.static)

    def _group_frame(self, members: list[SceneBody]) -> np.ndarray:
        return members[0].pose

    def _pieces_in(self, members: list[SceneBody], frame: np.ndarray):
        inv = invert(frame)
        out = []
        for body in members:
            rel = matmul(inv, body.pose)
            if body.plane:
                out.append((PlanePiece(), rel))
            else:
                out.extend((piece, matmul(rel, piece.frame)) for piece in body.built.pieces)
        return out

    def _centre_of_mass(self, members: list[SceneBody], frame: np.ndarray):
        """(mass, (4, 4) principal inertial frame in ``frame``, (3,) principal moments)."""
        if all(b.static for b in members):
            return 0.0, np.eye(4), None
        if len(members) == 1:  # pose-independent: once per part and mass, computed at the
            body = members[0]  # identity so that it does not depend on the first pose seen
            return self.cache.get(("mass", body.mass), body.built,
                                  lambda: inertial_frame([(body, np.eye(4))]))
        return inertial_frame([(b, matmul(invert(frame), b.pose)) for b in members
                               if not b.static])

    def _inertial(self, members: list[SceneBody], frame: np.ndarray):
        """:meth:`_centre_of_mass`, with the inertial frame as pybullet takes it (position,
        quaternion) and its inverse; a single body's, which do not depend on its pose, once
        per part, mass and staticness."""
        def make():
            mass, com_frame, moments = self._centre_of_mass(members, frame)
            return mass, com_frame, moments, *to_pybullet(com_frame), invert(com_frame)

        if len(members) > 1:
            return make()
        body = members[0]
        if body.built is None:  # a plane: static, nothing to share
            return make()
        return self.cache.get(("inertial", body.mass, body.static), body.built, make)

    def _build_free(self, members: list[SceneBody]):
        """A free rigid body (maximal coordinates), or a static one."""
        frame = self._group_frame(members)
        shape = self._shape(self._pieces_in(members, frame))
        mass, com_frame, moments, ipos, iorn, com_inverse = self._inertial(members, frame)
        pos, orn = to_pybullet(frame)
        uid = self.engine.createMultiBody(
            baseMass=mass, baseCollisionShapeIndex=shape, basePosition=pos,
            baseOrientation=orn, baseInertialFramePosition=ipos,
            baseInertialFrameOrientation=iorn, useMaximalCoordinates=True)
        self._finish_free(uid, members, mass, moments)
        to_part = matmul(com_inverse, invert(frame))
        for b in members:
            self.handles[b.name] = Handle(uid, -1, matmul(to_part, b.pose))

    def _build_batch(self, bodies: list[SceneBody]):
        """Several free bodies with the same part and properties, created in one call."""
        if len(bodies) == 1:
            return self._build_free(bodies)
        shape = self._shape([(piece, piece.frame) for piece in bodies[0].built.pieces])
        mass, com_frame, moments, ipos, iorn, to_part = self._inertial(bodies[:1],
                                                                       bodies[0].pose)
        uids = self.engine.createMultiBody(
            baseMass=mass, baseCollisionShapeIndex=shape,
            baseInertialFramePosition=ipos, baseInertialFrameOrientation=iorn,
            batchPositions=[b.pose[:3, 3].tolist() for b in bodies],
            useMaximalCoordinates=True)
        for uid, body in zip(uids, bodies, strict=True):
            pos, orn = to_pybullet(matmul(body.pose, com_frame))  # the reset takes the COM frame
            self.engine.resetBasePositionAndOrientation(uid, pos, orn)
            self._finish_free(uid, [body], mass, moments)
            self.handles[body.name] = Handle(uid, -1, to_part)

    def _finish_free(self, uid: int, members: list[SceneBody], mass: float, moments) -> None:
        if moments is None:
            self._surface(uid, -1, members[0])
            return
        extra = {"ccdSweptSphereRadius": self._ccd_radius(members)} if self.settings.ccd else {}
        self._dynamics(uid, -1, members[0], mass, moments, **extra)

    def _build_hinged(self, members: list[SceneBody], hinge):
        """A two-link multibody: a fixed base (the axle body, or nothing for the world)
        and the moving body on a revolute joint."""
        scene = self.scene
        if hinge.fixed is not None:
            base_group = next((g for g in scene.welds if hinge.fixed in g), (hinge.fixed,))
            base_members = [scene.bodies[n] for n in base_group]
            if not all(b.static for b in base_members):
                raise ValueError(f"hinge {hinge.moving!r}: its base {hinge.fixed!r} must be "
                                 "static (chains of moving bodies are not supported yet)")
            base_frame = self._group_frame(base_members)
            base_shape = self._shape(self._pieces_in(base_members, base_frame))
        else:
            base_members, base_frame, base_shape = [], np.eye(4), -1
        # link frame: at the hinge point, axis along its local z
        frame = self._group_frame(members)
        axis = hinge.axis / norm(hinge.axis)
        link_frame = np.eye(4)
        link_frame[:3, :3] = frame[:3, :3]
        link_frame[:3, 3] = hinge.point
        local_axis = matmul(frame[:3, :3].T, axis)
        shape = self._shape(self._pieces_in(members, link_frame))
        mass, com_frame, moments = inertial_frame(
            [(b, matmul(invert(link_frame), b.pose)) for b in members if not b.static])
        link_in_base = matmul(invert(base_frame), link_frame)
        bpos, born = to_pybullet(base_frame)
        lpos, lorn = to_pybullet(link_in_base)
        ipos, iorn = to_pybullet(com_frame)
        uid = self.engine.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=base_shape, basePosition=bpos,
            baseOrientation=born, linkMasses=[mass], linkCollisionShapeIndices=[shape],
            linkVisualShapeIndices=[-1], linkPositions=[lpos], linkOrientations=[lorn],
            linkInertialFramePositions=[ipos], linkInertialFrameOrientations=[iorn],
            linkParentIndices=[0], linkJointTypes=[pb.JOINT_REVOLUTE],
            linkJointAxis=[local_axis.tolist()])
        self.engine.setJointMotorControl2(uid, 0, pb.VELOCITY_CONTROL, force=0)
        self.engine.changeDynamics(uid, 0, jointDamping=0.0)
        self._dynamics(uid, 0, members[0], mass, moments)
        self.engine.changeDynamics(uid, -1, linearDamping=0, angularDamping=0)
        if base_members:
            self._surface(uid, -1, base_members[0])
        for b in base_members:
            self.handles[b.name] = Handle(uid, -1, matmul(invert(base_frame), b.pose))
        for b in members:
            self.handles[b.name] = Handle(uid, 0, matmul(matmul(invert(com_frame), invert(link_frame)),
                                                  b.pose))

    def _surface(self, uid, link, body: SceneBody, **extra):
        phys = body.physical
        self.engine.changeDynamics(
            uid, link, lateralFriction=phys.friction, restitution=phys.restitution,
            rollingFriction=phys.rolling_friction, spinningFriction=phys.spinning_friction, **extra)

    def _dynamics(self, uid, link, body: SceneBody, mass: float, moments, **extra):
        phys = body.physical
        # Two calls, each working around a pybullet 3.2.7 quirk: changing only the inertia of a
        # maximal-coordinates body zeroes its mass, so the mass goes with it; and a mass change
        # in the same call as a damping change on a multibody link also gives the (fixed) base
        # that mass, so the base starts to fall.
        self._surface(uid, link, body, linearDamping=phys.linear_damping,
                      angularDamping=phys.angular_damping,
                      activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, **extra)
        self.engine.changeDynamics(uid, link, mass=mass, localInertiaDiagonal=moments.tolist())

    def _ccd_radius(self, members: list[SceneBody]) -> float:
        """Swept-sphere radius: a bit under half the body's thinnest extent."""
        def make():
            extents = [np.ptp(np.asarray(b.built.bbox), axis=0).min() for b in members if b.built]
            return 0.4 * float(min(extents))

        return make() if len(members) > 1 else self.cache.get("ccd radius", members[0].built, make)

    # -- state -------------------------------------------------------------------------------

    # _LINK_STATE: a hinged body is a multibody link, and pybullet's getLinkState without
    # forward kinematics reports the link's cached world transform, which stepSimulation sets
    # (btMultiBody::forwardKinematics) before it integrates the positions: after a step it is
    # the step before's pose, while the collision shape has moved on; the world velocity of
    # its centre of mass is turned by that stale rotation too. Every reader of a link asks
    # for forward kinematics (under 1 us a call).

    # Readers call pybullet with the world's client id themselves, as a positional argument:
    # they run at every step, and the engine's bound functions (keyword arguments) cost
    # 0.3-0.7 us more per call.

    def step(self) -> None:
        self._step()
        self.time += self._dt

    def stepper(self):
        """The physics step as a function of no arguments, for a step loop that sets
        :attr:`time` itself (one Python call less per step than :meth:`step`)."""
        return self._step

    def _com_state(self, h: Handle, velocity: bool = False):
        if h.link < 0:
            pos, orn = pb.getBasePositionAndOrientation(h.uid, physicsClientId=self.cid)
            if velocity:
                return pos, orn, *pb.getBaseVelocity(h.uid, physicsClientId=self.cid)
            return pos, orn
        # with forward kinematics: see _LINK_STATE
        state = pb.getLinkState(h.uid, h.link, computeLinkVelocity=int(velocity),
                                computeForwardKinematics=1, physicsClientId=self.cid)
        if velocity:
            return state[0], state[1], state[6], state[7]
        return state[0], state[1]

    def pose(self, name: str) -> np.ndarray:
        """(4, 4) world transform of the body's part frame."""
        h = self.handles[name]
        pos, orn = self._com_state(h)
        return matmul(from_pybullet(pos, orn), h.com_to_part)

    def velocity(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Linear velocity (3,) m/s of the body's rigid body's centre of mass, angular (3,) rad/s."""
        h = self.handles[name]
        _, _, lin, ang = self._com_state(h, velocity=True)
        return np.asarray(lin), np.asarray(ang)

    # -- fast readers: closures for the per-step event checks (plain floats, no numpy) -------

    def velocity_reader(self, name: str):
        """A function returning ((vx, vy, vz) m/s, (wx, wy, wz) rad/s) of the body's centre
        of mass now."""
        h, cid = self.handles[name], self.cid
        if h.link < 0:  # pybullet's own function: no Python frame of ours per call
            return functools.partial(pb.getBaseVelocity, h.uid, cid)
        get_state, uid, link = pb.getLinkState, h.uid, h.link

        def read():  # computeLinkVelocity=1, computeForwardKinematics=1 (_LINK_STATE)
            state = get_state(uid, link, 1, 1, cid)
            return state[6], state[7]

        return read

    def frame_reader(self, name: str):
        """A function returning the world position (x, y, z) and (x, y, z, w) quaternion of the
        body's centre-of-mass frame now (:attr:`Handle.com_to_part` leads to its part frame)."""
        h, cid = self.handles[name], self.cid
        if h.link < 0:  # pybullet's own function: no Python frame of ours per call
            return functools.partial(pb.getBasePositionAndOrientation, h.uid, cid)
        get_state, uid, link = pb.getLinkState, h.uid, h.link
        return lambda: get_state(uid, link, 0, 1, cid)[:2]  # computeForwardKinematics=1

    def up_reader(self, name: str, direction) -> callable:
        """A function returning the world z component of ``direction`` (3,), a unit vector fixed
        in the body's part frame: the cosine of its angle to the vertical."""
        h = self.handles[name]
        direction = tuple(matmul(h.com_to_part[:3, :3], direction).tolist())
        frame = self.frame_reader(name)  # through the rotation of the centre-of-mass frame
        return lambda: rotated_z(frame()[1], direction)

    def point_reader(self, name: str, point):
        """A function returning the world position (x, y, z) of ``point`` (3,), a point fixed
        in the body's part frame."""
        h = self.handles[name]
        point = tuple((matmul(h.com_to_part[:3, :3], point) + h.com_to_part[:3, 3]).tolist())
        frame = self.frame_reader(name)

        def read():
            position, orientation = frame()
            return moved_point(position, orientation, point)

        return read

    def contact_reader(self, a: str, b: str, tolerance: float):
        """A function returning True while bodies ``a`` and ``b`` are within ``tolerance`` m.

        After the first step it reads the engine's contact manifolds, which hold every point
        pair closer than the contact breaking threshold (cheaper than a fresh closest-points
        query on compound bodies); before it, or for a tolerance wider than that threshold, it
        asks for the closest points.
        """
        ha, hb, cid = self.handles[a], self.handles[b], self.cid
        if ha.uid == hb.uid:
            return lambda: True  # welded or hinged together
        closest, contacts = pb.getClosestPoints, pb.getContactPoints
        ua, ub, la, lb = ha.uid, hb.uid, ha.link, hb.link
        if tolerance > self.settings.contact_breaking_threshold:
            return lambda: bool(closest(ua, ub, tolerance, la, lb, physicsClientId=cid))

        def read():
            if self.time == 0.0:
                return bool(closest(ua, ub, tolerance, la, lb, physicsClientId=cid))
            for c in contacts(ua, ub, la, lb, cid):  # a loop: any() over a generator costs more
                if c[8] <= tolerance:
                    return True
            return False

        return read
