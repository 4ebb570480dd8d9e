"""Conformance: the collision geometry pybullet builds is the exact pieces, every one of them.

pybullet's ``createCollisionShapeArray`` keeps 16 children and silently drops the others
(bullet3#2185), so a body of more pieces (a goblet has 33) once collided with only part of
itself while the validity test used all of it. For every part family at its example
parameters, every body of the shipped scenarios and rigid bodies made of many pieces (weld
groups, hinged bodies, hinge bases), two checks:

* count: pybullet reports one collision shape per piece (``getCollisionShapeData``, read on a
  reduced-coordinates twin sharing the shape, as pybullet answers nothing for a
  maximal-coordinates body);
* probe: for every piece, a ray from outside toward a point inside it, along a direction on
  which that piece is the first thing met, hits the right pybullet body where the exact piece
  begins, to 20 um: every kind of piece, convex hulls of compounds included (their hulls are
  inset by the collision margin they carry, :mod:`rgmcad.sim.shapes`). A missing piece
  leaves the ray to hit nothing, or something farther.
"""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from _support import scene_of, tiny
from scipy.spatial import ConvexHull

from rgmcad.geometry import invert
from rgmcad.parts.family import load_families, params_dict
from rgmcad.parts.pieces import (
    BoxPiece,
    CapsulePiece,
    ConvexPiece,
    CylinderPiece,
    PlanePiece,
    SpherePiece,
)
from rgmcad.scene.bodies import Scene
from rgmcad.scene.loader import load_scenario
from rgmcad.sim.world import World

FAMILIES = load_families()
SCENARIOS = sorted((Path(__file__).parent.parent / "scenarios").glob("*.toml"))
TOL = 2e-5  # m: where a ray meets a piece, against the exact piece
HULL_PAD = 0.0  # m: how much earlier than the exact piece a hull may be met
CLEAR = 1e-3  # m: a probe ray keeps this far from the other pieces (grazing rays hit early)
GOBLET = {"inner_height": 0.11, "top_radius": 0.036, "bottom_radius": 0.025, "wall": 0.002}
TRACK = {"length": 0.3, "width": 0.025, "height": 0.006, "wall": 0.003}
NEVER = {"e": {"type": "stopping", "body": "a"}}


# --- exact geometry ---------------------------------------------------------------------------


_HULLS: dict[int, tuple[ConvexPiece, ConvexHull]] = {}


def _hull(piece: ConvexPiece) -> ConvexHull:
    cached = _HULLS.get(id(piece))
    if cached is None or cached[0] is not piece:
        cached = _HULLS[id(piece)] = (piece, ConvexHull(np.asarray(piece.vertices, float)))
    return cached[1]


def _halfspaces(piece, frame: np.ndarray, pad: float):
    """Inequalities ``n . x + d <= 0`` (world frame) of a piece grown by ``pad``, or None for
    a curved piece."""
    rot, origin = frame[:3, :3], frame[:3, 3]
    if isinstance(piece, ConvexPiece):
        eq = _hull(piece).equations
        normals = eq[:, :3] @ rot.T
        return normals, eq[:, 3] - normals @ origin - pad
    if isinstance(piece, BoxPiece):
        half = np.asarray(piece.size, float) / 2 + pad
        normals = np.vstack([rot.T, -rot.T])
        return normals, -np.concatenate([half, half]) - normals @ origin
    if isinstance(piece, PlanePiece):
        normal = rot[:, 2:3].T
        return normal, -normal @ origin - pad
    return None


def _entry(piece, frame: np.ndarray, start: np.ndarray, end: np.ndarray, pad: float = 0.0):
    """Distance (m) from ``start`` at which the segment enters the piece grown by ``pad``;
    inf if it does not."""
    if isinstance(piece, CapsulePiece):  # convex: entering it is entering one of its parts
        ends = [frame @ np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, z], [0, 0, 0, 1]])
                for z in (-piece.length / 2, piece.length / 2)]
        return min(_entry(CylinderPiece(piece.radius, piece.length), frame, start, end, pad),
                   *(_entry(SpherePiece(piece.radius), e, start, end, pad) for e in ends))
    u = end - start
    length = float(np.linalg.norm(u))
    lo, hi = 0.0, 1.0
    planes = _halfspaces(piece, frame, pad)
    if planes is None:  # sphere or cylinder: in the piece's frame
        s = invert(frame)[:3] @ np.append(start, 1.0)
        v = frame[:3, :3].T @ u
        if isinstance(piece, SpherePiece):
            lo, hi = _quadratic(s, v, piece.radius + pad, lo, hi)
        else:
            lo, hi = _quadratic(s[:2], v[:2], piece.radius + pad, lo, hi)
            lo, hi = _slab(s[2], v[2], piece.height / 2 + pad, lo, hi)
    else:
        normals, offsets = planes
        a, b = normals @ u, normals @ start + offsets
        parallel = np.abs(a) < 1e-15
        if (b[parallel] > 0).any():
            return np.inf
        with np.errstate(divide="ignore"):
            t = -b / a
        lo = max(lo, t[~parallel & (a < 0)].max(initial=lo))
        hi = min(hi, t[~parallel & (a > 0)].min(initial=hi))
    return lo * length if lo <= hi else np.inf


def _quadratic(s, v, radius, lo, hi):
    """Clip [lo, hi] to |s + t v| <= radius."""
    a, b, c = v @ v, 2 * s @ v, s @ s - radius**2
    if a < 1e-30:
        return (lo, hi) if c <= 0 else (1.0, 0.0)
    disc = b * b - 4 * a * c
    if disc < 0:
        return 1.0, 0.0
    root = np.sqrt(disc)
    return max(lo, (-b - root) / (2 * a)), min(hi, (-b + root) / (2 * a))


def _slab(s, v, half, lo, hi):
    """Clip [lo, hi] to |s + t v| <= half."""
    if abs(v) < 1e-15:
        return (lo, hi) if abs(s) <= half else (1.0, 0.0)
    t0, t1 = sorted(((-half - s) / v, (half - s) / v))
    return max(lo, t0), min(hi, t1)


def _inside_point_and_directions(piece, frame: np.ndarray):
    """A point inside the piece and unit directions to come at it from."""
    rot = frame[:3, :3]
    # faces first: a primitive's edges and corners are rounded by its margin
    axes = sorted((np.array(d, float) for d in itertools.product((-1, 0, 1), repeat=3) if any(d)),
                  key=lambda d: np.count_nonzero(d))
    dirs = [rot @ (d / np.linalg.norm(d)) for d in axes]
    if isinstance(piece, ConvexPiece):
        verts = np.asarray(piece.vertices, float)
        hull = _hull(piece)
        # outward face normals, largest faces first
        areas = [np.linalg.norm(np.cross(*(verts[s[1:]] - verts[s[0]]))) for s in hull.simplices]
        normals = hull.equations[np.argsort(areas)[::-1], :3]
        dirs = [rot @ n for n in normals] + dirs
        return frame[:3, :3] @ verts.mean(axis=0) + frame[:3, 3], dirs
    if isinstance(piece, PlanePiece):
        return frame[:3, 3] - 0.005 * rot[:, 2], [rot[:, 2]]
    return frame[:3, 3].copy(), dirs


def _pad(piece, hull_boxes: bool) -> float:
    return HULL_PAD if isinstance(piece, ConvexPiece) or (hull_boxes and isinstance(
        piece, BoxPiece)) else 0.0


# --- the checks -------------------------------------------------------------------------------


@pytest.fixture
def shapes(monkeypatch):
    """Every collision shape a World makes, with the pieces it was made from."""
    made = []
    original = World._shape

    def recording(self, pieces):
        shape = original(self, pieces)
        made.append((shape, [piece for piece, _ in pieces]))
        return shape

    monkeypatch.setattr(World, "_shape", recording)
    return made


GEOM = {BoxPiece: pb.GEOM_BOX, SpherePiece: pb.GEOM_SPHERE, CylinderPiece: pb.GEOM_CYLINDER,
        CapsulePiece: pb.GEOM_CAPSULE, ConvexPiece: pb.GEOM_MESH, PlanePiece: pb.GEOM_PLANE}


def check_counts(world: World, shapes) -> None:
    """Every shape the world made reports one collision shape per piece, of the piece's kind
    (a box may come as a mesh: the hull of its corners)."""
    for shape, pieces in shapes:
        twin = pb.createMultiBody(0.0, shape, basePosition=[100, 0, 0],
                                  physicsClientId=world.cid)
        data = pb.getCollisionShapeData(twin, -1, physicsClientId=world.cid)
        pb.removeBody(twin, physicsClientId=world.cid)
        reported = np.bincount([s[2] for s in data], minlength=16)
        wanted = np.bincount([GEOM[type(p)] for p in pieces], minlength=16)
        assert len(data) == len(pieces)
        boxes_as_meshes = wanted[pb.GEOM_BOX] - reported[pb.GEOM_BOX]
        assert 0 <= boxes_as_meshes == reported[pb.GEOM_MESH] - wanted[pb.GEOM_MESH]
        others = [g for g in range(16) if g not in (pb.GEOM_BOX, pb.GEOM_MESH)]
        assert (reported[others] == wanted[others]).all()


def _clear_ray(i: int, pieces, hull_boxes: bool):
    """(point inside piece ``i``, ray start, distance to the piece): a ray that meets piece
    ``i`` before any other, keeping clear of the others (by CLEAR, or less if it must)."""
    piece, frame, _ = pieces[i]
    inside, dirs = _inside_point_and_directions(piece, frame)
    reach = 1.0 if isinstance(piece, PlanePiece) else 0.5
    for clear in (CLEAR, CLEAR / 2, 0.0):
        for d in dirs:
            start = inside + reach * d
            own = _entry(piece, frame, start, inside)
            others = (_entry(p, f, start, inside, _pad(p, hull_boxes) + clear + 2 * TOL)
                      for j, (p, f, _) in enumerate(pieces) if j != i)
            if own < np.inf and min(others, default=np.inf) > own + 2 * TOL:
                return inside, start, own
    raise AssertionError(f"no clear ray to piece {i} ({type(piece).__name__})")


def check_probes(world: World, hull_boxes: bool = False) -> None:
    """Ray-probe every piece of every body of ``world``."""
    world.step()  # rays miss parts of a hinged link until the first step
    pieces = []  # (piece, world frame, (uid, link))
    for name, body in world.scene.bodies.items():
        h = world.handles[name]
        pose = world.pose(name)
        own = [PlanePiece()] if body.plane else body.built.pieces
        pieces.extend((p, pose @ np.asarray(p.frame, float), (h.uid, h.link)) for p in own)
    starts, ends, wanted = [], [], []
    for i, (piece, frame, owner) in enumerate(pieces):
        inside, start, own = _clear_ray(i, pieces, hull_boxes)
        early = _entry(piece, frame, start, inside, _pad(piece, hull_boxes)) if _pad(
            piece, hull_boxes) else own
        starts.append(start)
        ends.append(inside)
        wanted.append((owner, early, own, type(piece).__name__))
    hits = pb.rayTestBatch([s.tolist() for s in starts], [e.tolist() for e in ends],
                           physicsClientId=world.cid)
    missed = []
    for i, (hit, (owner, early, exact, kind), s, e) in enumerate(
            zip(hits, wanted, starts, ends, strict=True)):
        at = hit[2] * np.linalg.norm(e - s)
        if hit[:2] != owner or not early - TOL <= at <= exact + TOL:
            missed.append(f"piece {i} ({kind}): hit {hit[:2]} at {at:.6f} m, wanted {owner} in "
                          f"[{early:.6f}, {exact:.6f}]")
    assert not missed, f"{len(missed)} of {len(pieces)} pieces missing:\n" + "\n".join(missed)


def check(scene: Scene, settings, shapes, hull_boxes: bool = False):
    shapes.clear()
    with World(scene, settings) as world:
        check_probes(world, hull_boxes)
        check_counts(world, shapes)


# --- every part family --------------------------------------------------------------------------


def _example(family):
    return sys.modules[family.params.__module__].EXAMPLE


@pytest.mark.parametrize("name", sorted(FAMILIES))
def test_every_family_collides_with_all_its_pieces(name, shapes):
    family = FAMILIES[name]
    obj = {"part": name, "params": params_dict(_example(family))}
    if not family.infinite:
        obj["mass"] = 0.05
    # two of each: identical single bodies are created in one batch
    objects = {"a": obj} if family.infinite else {"a": obj, "b": {**obj, "pose": {"x": 0.5}}}
    sc = tiny(objects, NEVER)
    check(scene_of(sc), sc.settings, shapes)


# --- every rigid body of the shipped scenarios --------------------------------------------------


def _rigid_units(scene: Scene) -> list[set[str]]:
    """Sets of scene bodies that end up in one pybullet body: weld groups, and a hinged group
    with its base."""
    group_of = {n: set(g) for g in scene.welds for n in g}
    units = {}
    for name in scene.bodies:
        units.setdefault(frozenset(group_of.get(name, {name})), None)
    merged = [set(u) for u in units]
    for h in scene.hinges:
        if h.fixed is None:
            continue
        a = next(u for u in merged if h.moving in u)
        b = next(u for u in merged if h.fixed in u)
        if a is not b:
            a |= b
            merged.remove(b)
    return merged


def _sub_scene(scene: Scene, names: set[str]) -> Scene:
    return Scene({n: b for n, b in scene.bodies.items() if n in names},
                 tuple(h for h in scene.hinges if h.moving in names),
                 tuple(g for g in scene.welds if g[0] in names), scene.values)


@pytest.mark.parametrize("path", SCENARIOS, ids=[p.stem for p in SCENARIOS])
def test_every_body_of_the_shipped_scenarios_collides_with_all_its_pieces(path, shapes):
    scenario = load_scenario(path)
    scene = scene_of(scenario)
    for unit in _rigid_units(scene):
        check(_sub_scene(scene, unit), scenario.settings, shapes)


# --- rigid bodies of many pieces ----------------------------------------------------------------
# No other test declares a weld or a hinge: these stand for the scenarios users write.


def _goblet(**extra):
    return {"part": "goblet", "params": GOBLET, **extra}


MANY = {
    "goblet welded to a track": (
        {"a": _goblet(mass=0.05), "t": {"part": "track", "params": TRACK, "mass": 0.02,
                                        "pose": {"x": 0.2}}},
        [{"kind": "weld", "objects": ["t", "a"]}], False),
    "six tracks welded (18 boxes)": (
        {"a": {"part": "track", "params": TRACK, "mass": 0.02},
         **{f"t{i}": {"part": "track", "params": TRACK, "mass": 0.02,
                      "pose": {"y": 0.03 * i, "z": 0.01 * i, "heading": 10 * i}}
            for i in range(1, 6)}},
        [{"kind": "weld", "objects": ["a", f"t{i}"]} for i in range(1, 6)], True),
    "seventeen planks welded": (
        {"a": {"part": "box", "params": {"length": 0.1, "width": 0.02, "height": 0.005},
               "mass": 0.01},
         **{f"p{i}": {"part": "box", "params": {"length": 0.1, "width": 0.02, "height": 0.005},
                      "mass": 0.01, "pose": {"z": 0.01 * i, "heading": 20 * i}}
            for i in range(1, 17)}},
        [{"kind": "weld", "objects": ["a", f"p{i}"]} for i in range(1, 17)], True),
    "goblet hinged to the world": (
        {"a": _goblet(mass=0.05)},
        [{"kind": "hinge", "objects": ["a"], "point": [0, 0, 0.05], "axis": [1, 0, 0]}], False),
    "lever carrying a goblet": (
        {"a": {"part": "lever", "mass": 0.02,
               "params": {"length": 0.35, "width": 0.025, "thickness": 0.005,
                          "axle_radius": 0.002, "axle_length": 0.0375}},
         "g": _goblet(mass=0.05, pose={"x": 0.12, "z": 0.0025})},
        [{"kind": "weld", "objects": ["a", "g"]}], False),
    "paddle hinged to a static goblet": (
        {"a": {"part": "box", "params": {"length": 0.06, "width": 0.01, "height": 0.002},
               "mass": 0.01, "pose": {"z": 0.14}},
         "g": _goblet(), "b": {"part": "box", "params": {"length": 0.01, "width": 0.01,
                                                            "height": 0.02}, "pose": {"z": 0.122}}},
        [{"kind": "weld", "objects": ["g", "b"]},
         {"kind": "hinge", "objects": ["a", "g"], "point": [0, 0, 0], "axis": [0, 1, 0]}], False),
}


@pytest.mark.parametrize("case", list(MANY))
def test_rigid_bodies_of_many_pieces_collide_with_all_of_them(case, shapes):
    objects, joints, hull_boxes = MANY[case]
    sc = tiny(objects, NEVER, joints=joints)
    check(scene_of(sc), sc.settings, shapes, hull_boxes)


def test_too_many_round_pieces_in_one_body_are_refused():
    ball = {"part": "ball", "params": {"radius": 0.01}, "mass": 0.01}
    balls = {"a": ball, **{f"b{i}": {**ball, "pose": {"x": 0.02 * i}} for i in range(1, 17)}}
    sc = tiny(balls, NEVER, joints=[{"kind": "weld", "objects": ["a", f"b{i}"]}
                                    for i in range(1, 17)])
    with pytest.raises(ValueError, match="16"):
        World(scene_of(sc), sc.settings)
