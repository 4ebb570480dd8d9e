"""The pybullet view of a scene: a world built from a :class:`~rgmcad.scene.bodies.Scene`.

Each process owns one DIRECT client (:func:`client`); every world resets it and rebuilds from
scratch, because restoring a saved state does not reproduce a fresh run (stale contact
caches). Engine workarounds, all in this module:

* free bodies use maximal coordinates: pybullet's default multibodies add damping and ignore
  continuous collision detection (CCD);
* a hinge is a two-link multibody (fixed base = the axle or the world, revolute link = the
  moving body) whose default velocity motor is switched off; ``createConstraint`` has no hinge
  (bullet3 issues #2005, #4701);
* convex mesh pieces get a 0.1 mm collision margin instead of pybullet's 1 mm, and compound
  bodies take convex pieces from OBJ files because ``createCollisionShapeArray`` accepts no
  raw vertices;
* ``createCollisionShapeArray`` keeps 16 children and silently drops the rest (bullet3#2185):
  a body of more pieces gets one OBJ file of several objects per body, which pybullet loads as
  one convex hull child per object (:func:`_packed`);
* sleeping is disabled, so slow levers are never frozen;
* inertia comes from the CAD solid (principal moments and axes), not from the collision
  shape's bounding box.

Positions and orientations are read as (4, 4) transforms of each body's *part frame*.
"""

from __future__ import annotations

import atexit
import hashlib
import itertools
import os
import shutil
import tempfile
from dataclasses import dataclass

import numpy as np
import pybullet as pb

from rgmcad.geometry import from_pybullet, invert, to_pybullet, transform_points
from rgmcad.parts.family import BoxPiece, ConvexPiece, CylinderPiece, Piece, PlanePiece, SpherePiece
from rgmcad.scene.bodies import Scene, SceneBody
from rgmcad.scene.scenario import SimulationSettings

_CLIENT: int | None = None


def client() -> int:
    """This process's pybullet DIRECT client, connected on first use."""
    global _CLIENT
    if _CLIENT is None or not pb.isConnected(_CLIENT):
        _CLIENT = pb.connect(pb.DIRECT)
    return _CLIENT


@dataclass(frozen=True)
class Handle:
    """Where a scene body lives in pybullet: body id, link index (-1: base), and the
    (4, 4) transform from the link's centre-of-mass frame to the part frame."""

    uid: int
    link: int
    com_to_part: np.ndarray


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
        com = pose[:3, :3] @ body.built.centre_of_mass + pose[:3, 3]
        inertia = rot @ (body.built.inertia_unit * (m / body.built.volume)) @ rot.T
        parts.append((m, com, inertia))
        total += m
        moment += m * com
    com = moment / total
    inertia = np.zeros((3, 3))
    for m, c, i in parts:
        d = c - com
        inertia += i + m * (d @ d * np.eye(3) - np.outer(d, d))  # parallel axis theorem
    return _Mass(total, com, inertia)


def _principal(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Principal moments (3,) and a right-handed rotation (3, 3) whose columns are the axes."""
    moments, axes = np.linalg.eigh(0.5 * (inertia + inertia.T))
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1
    return np.maximum(moments, 1e-12), axes


class _ObjFiles:
    """Convex pieces written once per process as OBJ files (pybullet compounds need files).

    A path is never rewritten: pybullet caches file contents by name (``enableFileCaching``).
    """

    def __init__(self):
        self.dir = None
        self.files: dict[object, tuple[tuple, str]] = {}

    def path(self, piece: ConvexPiece) -> str:
        """A file holding the piece's vertices as given (its frame is the child's frame)."""
        return self._file(id(piece), (piece,), lambda: [np.asarray(piece.vertices, float)])

    def path_of_hulls(self, hulls: _Hulls) -> str:
        """A file of one object per piece, each placed at its frame in ``hulls``."""
        pieces = tuple(p for p, _ in hulls.pieces)
        if not hulls.baked:  # frames are the pieces' own: the pieces say it all
            return self._file(tuple(map(id, pieces)), pieces, lambda: _placed(hulls))
        blocks = _placed(hulls)
        digest = hashlib.sha256(b"".join(b.tobytes() for b in blocks)).hexdigest()
        return self._file(digest, (), lambda: blocks)

    def _file(self, key, owners: tuple, objects) -> str:
        cached = self.files.get(key)
        if cached is not None and all(a is b for a, b in zip(cached[0], owners, strict=True)):
            return cached[1]
        if self.dir is None:
            self.dir = tempfile.mkdtemp(prefix="rgmcad-pieces-")
            atexit.register(shutil.rmtree, self.dir, True)
        from scipy.spatial import ConvexHull

        blocks = objects()
        path = os.path.join(self.dir, f"piece{len(self.files)}.obj")
        with open(path, "w") as f:
            offset = 0
            for i, verts in enumerate(blocks):
                if len(blocks) > 1:
                    f.write(f"o piece{i}\n")
                hull = ConvexHull(verts)
                f.write("".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in verts))
                f.write("".join(f"f {a + offset + 1} {b + offset + 1} {c + offset + 1}\n"
                                for a, b, c in hull.simplices))
                offset += len(verts)
        self.files[key] = (owners, path)
        return path


@dataclass(frozen=True, eq=False)
class _Hulls:
    """Pieces loaded from one OBJ file of one object per piece: a single entry of
    ``createCollisionShapeArray`` from which pybullet adds one convex hull child per object
    to the compound, however many. Each piece (convex, or a box as the hull of its corners)
    comes with its frame in the entry's frame: its own frame (pieces of one scene body), or
    its frame in the whole body (``baked``: the file then depends on the layout)."""

    pieces: tuple[tuple[ConvexPiece | BoxPiece, np.ndarray], ...]
    baked: bool = False


def _placed(hulls: _Hulls) -> list[np.ndarray]:
    """(n, 3) vertices of each piece, placed at its frame."""
    out = []
    for piece, frame in hulls.pieces:
        if isinstance(piece, BoxPiece):
            corners = np.array(list(itertools.product((-0.5, 0.5), repeat=3)))
            verts = corners * np.asarray(piece.size, float)
        else:
            verts = np.asarray(piece.vertices, float)
        if not np.array_equal(frame, np.eye(4)):  # else as written for one piece, bit for bit
            verts = transform_points(np.asarray(frame, float), verts)
        out.append(verts)
    return out


ARRAY_CHILDREN = 16
"""Children ``createCollisionShapeArray`` keeps; it silently drops the others (bullet3#2185)."""


def _packed(pieces: list[tuple[Piece, np.ndarray]]) -> list[tuple[Piece | _Hulls, np.ndarray]]:
    """At most :data:`ARRAY_CHILDREN` entries standing for more pieces, every piece colliding.

    Each scene body's convex pieces become one :class:`_Hulls` entry (a scene body: the pieces
    sharing ``frame @ inv(piece.frame)``), so its file does not depend on the layout. Boxes,
    spheres and cylinders stay exact primitives while they fit. If they do not, boxes join their
    body's hulls as the hull of their 8 corners (the same solid, but padded outward by a hull's
    margin like the other hulls); if that is still too many entries (many welded bodies), all
    hulls and the boxes that must go are baked into one file in the body's frame. Spheres and
    cylinders have no exact hull: more than fit is an error.
    """
    if any(isinstance(piece, PlanePiece) for piece, _ in pieces):
        raise ValueError("a plane cannot be part of a compound body")
    # each piece's scene body frame, frame @ inv(piece.frame), for all pieces at once
    own = np.array([piece.frame for piece, _ in pieces], float)
    inverse = np.tile(np.eye(4), (len(pieces), 1, 1))
    inverse[:, :3, :3] = own[:, :3, :3].transpose(0, 2, 1)
    inverse[:, :3, 3] = -np.einsum("nij,nj->ni", inverse[:, :3, :3], own[:, :3, 3])
    outers = np.array([frame for _, frame in pieces], float) @ inverse
    keys = np.round(outers, 12)  # merges frames equal to 1e-12; a body's first piece places it
    # key -> (the scene body's frame, its hull pieces, its primitives with their frames)
    bodies: dict[bytes, tuple[np.ndarray, list, list]] = {}
    for (piece, frame), outer, key in zip(pieces, outers, keys, strict=True):
        body = bodies.setdefault(key.tobytes(), (outer, [], []))
        if isinstance(piece, ConvexPiece):
            body[1].append(piece)
        else:
            body[2].append((piece, frame))
    excess = sum(len(p) + bool(h) for _, h, p in bodies.values()) - ARRAY_CHILDREN
    # demote boxes where it saves most: bodies that already have hulls, then the most boxes
    for _, hulls, prims in sorted(bodies.values(), key=lambda b: (
            not b[1], -sum(isinstance(p, BoxPiece) for p, _ in b[2]))):
        boxes = [i for i, (p, _) in enumerate(prims) if isinstance(p, BoxPiece)]
        if excess <= 0 or len(boxes) < (1 if hulls else 2):
            continue
        moved = boxes[-min(len(boxes), excess + (0 if hulls else 1)):]
        excess -= len(moved) - (0 if hulls else 1)
        hulls.extend(prims[i][0] for i in moved)
        prims[:] = [e for i, e in enumerate(prims) if i not in moved]
    if excess <= 0:
        out: list[tuple[Piece | _Hulls, np.ndarray]] = []
        for outer, hulls, prims in bodies.values():
            out.extend(prims)
            if hulls:
                out.append((_Hulls(tuple((p, np.asarray(p.frame, float)) for p in hulls)),
                            outer))
        return out
    # one baked file: every hull, and as many boxes as it takes
    baked = [(p, outer @ np.asarray(p.frame, float)) for outer, hulls, _ in bodies.values()
             for p in hulls]
    prims = [e for _, _, p in bodies.values() for e in p]
    boxes = [i for i, (p, _) in enumerate(prims) if isinstance(p, BoxPiece)]
    over = len(prims) + 1 - ARRAY_CHILDREN
    if over > len(boxes):
        raise ValueError(f"a rigid body of {len(pieces)} collision pieces: pybullet takes "
                         f"{ARRAY_CHILDREN} per body, and spheres and cylinders need one each "
                         f"({len(prims) - len(boxes)} here)")
    moved = boxes[len(boxes) - max(over, 0):]
    baked.extend(prims[i] for i in moved)
    return [e for i, e in enumerate(prims) if i not in moved] + [
        (_Hulls(tuple(baked), baked=True), np.eye(4))]


_OBJ = _ObjFiles()
_MASS_CACHE: dict[tuple, tuple] = {}


class World:
    """A pybullet world built from a scene. Owns the process client while it lives.

    Parameters
    ----------
    scene : the posed bodies and joints.
    settings : every engine parameter (time step, solver, CCD).
    """

    def __init__(self, scene: Scene, settings: SimulationSettings):
        self.scene = scene
        self.settings = settings
        self.cid = cid = client()
        pb.resetSimulation(physicsClientId=cid)
        pb.setGravity(0, 0, -settings.gravity, physicsClientId=cid)
        pb.setPhysicsEngineParameter(
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
            physicsClientId=cid,
        )
        self.handles: dict[str, Handle] = {}
        self._build()
        self.time = 0.0

    # -- construction ----------------------------------------------------------------------

    def _shape(self, pieces: list[tuple[Piece, np.ndarray]]) -> int:
        """A collision shape from pieces given with their (4, 4) frame in the shape frame."""
        cid = self.cid
        if len(pieces) == 1:
            piece, frame = pieces[0]
            pos, orn = to_pybullet(frame)
            common = dict(collisionFramePosition=pos, collisionFrameOrientation=orn,
                          physicsClientId=cid)
            if isinstance(piece, BoxPiece):
                return pb.createCollisionShape(pb.GEOM_BOX, halfExtents=[s / 2 for s in piece.size],
                                               **common)
            if isinstance(piece, SpherePiece):
                return pb.createCollisionShape(pb.GEOM_SPHERE, radius=piece.radius, **common)
            if isinstance(piece, CylinderPiece):
                return pb.createCollisionShape(pb.GEOM_CYLINDER, radius=piece.radius,
                                               height=piece.height, **common)
            if isinstance(piece, ConvexPiece):
                return pb.createCollisionShape(pb.GEOM_MESH, vertices=np.asarray(
                    piece.vertices, float).tolist(), **common)
            if isinstance(piece, PlanePiece):
                return pb.createCollisionShape(pb.GEOM_PLANE, planeNormal=[0, 0, 1], **common)
        if len(pieces) > ARRAY_CHILDREN:  # bodies of 16 pieces or fewer are built as they were
            pieces = _packed(pieces)
        types, radii, halves, lengths, files, positions, orientations = [], [], [], [], [], [], []
        for piece, frame in pieces:
            pos, orn = to_pybullet(frame)
            positions.append(pos)
            orientations.append(orn)
            radius, half, length, file = 0.0, [0.0, 0.0, 0.0], 0.0, ""
            if isinstance(piece, BoxPiece):
                types.append(pb.GEOM_BOX)
                half = [s / 2 for s in piece.size]
            elif isinstance(piece, SpherePiece):
                types.append(pb.GEOM_SPHERE)
                radius = piece.radius
            elif isinstance(piece, CylinderPiece):
                types.append(pb.GEOM_CYLINDER)
                radius, length = piece.radius, piece.height
            elif isinstance(piece, ConvexPiece):
                types.append(pb.GEOM_MESH)
                file = _OBJ.path(piece)
            elif isinstance(piece, _Hulls):
                types.append(pb.GEOM_MESH)
                file = _OBJ.path_of_hulls(piece)
            else:
                raise ValueError("a plane cannot be part of a compound body")
            radii.append(radius)
            halves.append(half)
            lengths.append(length)
            files.append(file)
        return pb.createCollisionShapeArray(
            types, radii=radii, halfExtents=halves, lengths=lengths, fileNames=files,
            meshScales=[[1, 1, 1]] * len(types), collisionFramePositions=positions,
            collisionFrameOrientations=orientations, physicsClientId=cid)

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
        # Identical single bodies (the dominoes of a run) are created in one batch call:
        # pybullet creates a body in ~120 us, a batch in ~13 us per body.
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
            rel = inv @ body.pose
            if body.plane:
                out.append((PlanePiece(), rel))
            else:
                out.extend((piece, rel @ piece.frame) for piece in body.built.pieces)
        return out

    def _centre_of_mass(self, members: list[SceneBody], frame: np.ndarray):
        """(mass, (4, 4) principal inertial frame in ``frame``, (3,) principal moments)."""
        if all(b.static for b in members):
            return 0.0, np.eye(4), None
        if len(members) == 1:  # pose-independent: cache per part and mass
            key = (id(members[0].built), members[0].mass)
            cached = _MASS_CACHE.get(key)
            if cached is not None and cached[0] is members[0].built:
                return cached[1:]
        if len(members) == 1:  # exactly the identity: the cached value must not depend on
            relative = [(members[0], np.eye(4))]  # the pose the process happened to see first
        else:
            relative = [(b, invert(frame) @ b.pose) for b in members if not b.static]
        props = _mass_of(relative)
        moments, axes = _principal(props.inertia)
        com_frame = np.eye(4)
        com_frame[:3, :3], com_frame[:3, 3] = axes, props.com
        if len(members) == 1:
            _MASS_CACHE[key] = (members[0].built, props.mass, com_frame, moments)
        return props.mass, com_frame, moments

    def _build_free(self, members: list[SceneBody]):
        """A free rigid body (maximal coordinates), or a static one."""
        frame = self._group_frame(members)
        shape = self._shape(self._pieces_in(members, frame))
        mass, com_frame, moments = self._centre_of_mass(members, frame)
        pos, orn = to_pybullet(frame)
        ipos, iorn = to_pybullet(com_frame)
        uid = pb.createMultiBody(
            baseMass=mass, baseCollisionShapeIndex=shape, basePosition=pos,
            baseOrientation=orn, baseInertialFramePosition=ipos,
            baseInertialFrameOrientation=iorn, useMaximalCoordinates=True,
            physicsClientId=self.cid)
        self._finish_free(uid, members, mass, moments)
        to_part = invert(com_frame) @ invert(frame)
        for b in members:
            self.handles[b.name] = Handle(uid, -1, to_part @ b.pose)

    def _build_batch(self, bodies: list[SceneBody]):
        """Several free bodies with the same part and properties, created in one call."""
        if len(bodies) == 1:
            return self._build_free(bodies)
        cid = self.cid
        shape = self._shape([(piece, piece.frame) for piece in bodies[0].built.pieces])
        mass, com_frame, moments = self._centre_of_mass(bodies[:1], bodies[0].pose)
        ipos, iorn = to_pybullet(com_frame)
        uids = pb.createMultiBody(
            baseMass=mass, baseCollisionShapeIndex=shape,
            baseInertialFramePosition=ipos, baseInertialFrameOrientation=iorn,
            batchPositions=[b.pose[:3, 3].tolist() for b in bodies],
            useMaximalCoordinates=True, physicsClientId=cid)
        to_part = invert(com_frame)
        for uid, body in zip(uids, bodies, strict=True):
            pos, orn = to_pybullet(body.pose @ com_frame)  # the reset takes the COM frame
            pb.resetBasePositionAndOrientation(uid, pos, orn, physicsClientId=cid)
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
        cid = self.cid
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
        axis = hinge.axis / np.linalg.norm(hinge.axis)
        link_frame = np.eye(4)
        link_frame[:3, :3] = frame[:3, :3]
        link_frame[:3, 3] = hinge.point
        local_axis = frame[:3, :3].T @ axis
        shape = self._shape(self._pieces_in(members, link_frame))
        props = _mass_of([(b, invert(link_frame) @ b.pose) for b in members if not b.static])
        moments, axes = _principal(props.inertia)
        com_frame = np.eye(4)
        com_frame[:3, :3], com_frame[:3, 3] = axes, props.com
        link_in_base = invert(base_frame) @ link_frame
        bpos, born = to_pybullet(base_frame)
        lpos, lorn = to_pybullet(link_in_base)
        ipos, iorn = to_pybullet(com_frame)
        uid = pb.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=base_shape, basePosition=bpos,
            baseOrientation=born, linkMasses=[props.mass], linkCollisionShapeIndices=[shape],
            linkVisualShapeIndices=[-1], linkPositions=[lpos], linkOrientations=[lorn],
            linkInertialFramePositions=[ipos], linkInertialFrameOrientations=[iorn],
            linkParentIndices=[0], linkJointTypes=[pb.JOINT_REVOLUTE],
            linkJointAxis=[local_axis.tolist()], physicsClientId=cid)
        pb.setJointMotorControl2(uid, 0, pb.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        pb.changeDynamics(uid, 0, jointDamping=0.0, physicsClientId=cid)
        self._dynamics(uid, 0, members[0], props.mass, moments)
        pb.changeDynamics(uid, -1, linearDamping=0, angularDamping=0, physicsClientId=cid)
        if base_members:
            self._surface(uid, -1, base_members[0])
        for b in base_members:
            self.handles[b.name] = Handle(uid, -1, invert(base_frame) @ b.pose)
        for b in members:
            self.handles[b.name] = Handle(uid, 0, invert(com_frame) @ invert(link_frame) @ b.pose)

    def _surface(self, uid, link, body: SceneBody, **extra):
        phys = body.physical
        if self._has_convex(body):
            extra["collisionMargin"] = self.settings.convex_margin
        pb.changeDynamics(
            uid, link, lateralFriction=phys.friction, restitution=phys.restitution,
            rollingFriction=phys.rolling_friction, spinningFriction=phys.spinning_friction,
            physicsClientId=self.cid, **extra)

    @staticmethod
    def _has_convex(body: SceneBody) -> bool:
        return body.built is not None and any(isinstance(p, ConvexPiece) for p in body.built.pieces)

    def _dynamics(self, uid, link, body: SceneBody, mass: float, moments, **extra):
        phys = body.physical
        # Two calls, each working around a pybullet 3.2.7 quirk: changing only the inertia of a
        # maximal-coordinates body zeroes its mass, so the mass goes with it; and a mass change
        # in the same call as a damping change on a multibody link also gives the (fixed) base
        # that mass, so the base starts to fall.
        self._surface(uid, link, body, linearDamping=phys.linear_damping,
                      angularDamping=phys.angular_damping,
                      activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING, **extra)
        pb.changeDynamics(uid, link, mass=mass, localInertiaDiagonal=moments.tolist(),
                          physicsClientId=self.cid)

    @staticmethod
    def _ccd_radius(members: list[SceneBody]) -> float:
        """Swept-sphere radius: a bit under half the body's thinnest extent."""
        extents = [np.ptp(np.asarray(b.built.bbox), axis=0).min() for b in members if b.built]
        return 0.4 * float(min(extents))

    # -- state -------------------------------------------------------------------------------

    def step(self) -> None:
        pb.stepSimulation(physicsClientId=self.cid)
        self.time += self.settings.timestep

    def _com_state(self, h: Handle, velocity: bool = False):
        if h.link < 0:
            pos, orn = pb.getBasePositionAndOrientation(h.uid, physicsClientId=self.cid)
            if velocity:
                return pos, orn, *pb.getBaseVelocity(h.uid, physicsClientId=self.cid)
            return pos, orn
        state = pb.getLinkState(h.uid, h.link, computeLinkVelocity=int(velocity),
                                physicsClientId=self.cid)
        if velocity:
            return state[0], state[1], state[6], state[7]
        return state[0], state[1]

    def pose(self, name: str) -> np.ndarray:
        """(4, 4) world transform of the body's part frame."""
        h = self.handles[name]
        pos, orn = self._com_state(h)
        return from_pybullet(pos, orn) @ h.com_to_part

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
        if h.link < 0:
            get_velocity, uid = pb.getBaseVelocity, h.uid
            return lambda: get_velocity(uid, physicsClientId=cid)
        get_state, uid, link = pb.getLinkState, h.uid, h.link

        def read():
            state = get_state(uid, link, computeLinkVelocity=1, physicsClientId=cid)
            return state[6], state[7]

        return read

    def up_reader(self, name: str, direction) -> callable:
        """A function returning the world z component of ``direction`` (3,), a unit vector fixed
        in the body's part frame: the cosine of its angle to the vertical."""
        h, cid = self.handles[name], self.cid
        a, b, c = (h.com_to_part[:3, :3] @ np.asarray(direction, float)).tolist()
        if h.link < 0:
            get_pose, uid = pb.getBasePositionAndOrientation, h.uid

            def orientation():
                return get_pose(uid, physicsClientId=cid)[1]
        else:
            get_state, uid, link = pb.getLinkState, h.uid, h.link

            def orientation():
                return get_state(uid, link, physicsClientId=cid)[1]

        def read():
            x, y, z, w = orientation()
            # third row of the rotation matrix of the centre-of-mass frame, times (a, b, c)
            return (2 * (x * z - y * w) * a + 2 * (y * z + x * w) * b
                    + (1 - 2 * (x * x + y * y)) * c)

        return read

    def point_reader(self, name: str, point):
        """A function returning the world position (x, y, z) of ``point`` (3,), a point fixed
        in the body's part frame."""
        h, cid = self.handles[name], self.cid
        a, b, c = (h.com_to_part[:3, :3] @ np.asarray(point, float) + h.com_to_part[:3, 3]).tolist()
        if h.link < 0:
            get_pose, uid = pb.getBasePositionAndOrientation, h.uid

            def state():
                return get_pose(uid, physicsClientId=cid)
        else:
            get_state, uid, link = pb.getLinkState, h.uid, h.link

            def state():
                return get_state(uid, link, physicsClientId=cid)[:2]

        def read():
            (px, py, pz), (x, y, z, w) = state()
            return (px + (1 - 2 * (y * y + z * z)) * a + 2 * (x * y - z * w) * b
                    + 2 * (x * z + y * w) * c,
                    py + 2 * (x * y + z * w) * a + (1 - 2 * (x * x + z * z)) * b
                    + 2 * (y * z - x * w) * c,
                    pz + 2 * (x * z - y * w) * a + 2 * (y * z + x * w) * b
                    + (1 - 2 * (x * x + y * y)) * c)

        return read

    def contact_reader(self, a: str, b: str, tolerance: float):
        """A function returning True while bodies ``a`` and ``b`` are within ``tolerance`` m.

        After the first step it reads the engine's contact manifolds, which hold every point
        pair closer than the contact breaking threshold (3 us against 5-15 us for a fresh
        closest-points query on compound bodies); before it, or for a tolerance wider than
        that threshold, it asks for the closest points.
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
            return any(c[8] <= tolerance for c in contacts(ua, ub, la, lb, physicsClientId=cid))

        return read
