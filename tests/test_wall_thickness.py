"""Law: the wall the physics sees is the part's wall.

Goblets, open boxes and tracks of generated sizes, in generated poses, as free bodies, in
welded compounds (of more than 16 pieces, where boxes become hulls) and as hinged links. Two
small probe spheres face each wall, one in the cavity and one outside, on a line normal to
it; pybullet's closest distances from each to the body give the wall the physics sees:

* each face is where the collision pieces put it (the exact distance to the union of the
  pieces' hulls), to 20 um;
* the wall's thickness (the probes' distance apart less both gaps) is the CAD's (the same
  measure on the part's tessellated solid), to 0.1 mm, goblets of any radius included: their
  pieces' two faces are parallel planes (parts/goblet.py).
"""

from __future__ import annotations

import math
import sys

import numpy as np
import pybullet as pb
import pytest
import trimesh
from _support import scene_of, tiny
from scipy.spatial import ConvexHull

from rgmcad.parts.family import load_families, params_dict
from rgmcad.sim.shapes import hull_vertices
from rgmcad.sim.world import World

PROBE = 5e-4  # m, radius of a probe sphere
FACE_TOL = 2e-5  # m, a face against the collision pieces
WALL_TOL = 1e-4  # m, a wall's thickness against the CAD's
NEVER = {"e": {"type": "stopping", "body": "a"}}
RNG_SEED = 49


def _goblet(rng):
    while True:
        p = {"inner_height": rng.uniform(0.04, 0.12), "top_radius": rng.uniform(0.02, 0.06),
             "bottom_radius": rng.uniform(0.015, 0.05), "wall": rng.uniform(0.0015, 0.004)}
        if p["top_radius"] - p["bottom_radius"] < 0.6 * p["inner_height"]:
            return p


def _open_box(rng):
    return {"length": rng.uniform(0.04, 0.14), "width": rng.uniform(0.03, 0.09),
            "height": rng.uniform(0.02, 0.09), "wall": rng.uniform(0.0015, 0.005)}


def _track(rng):
    return {"length": rng.uniform(0.1, 0.3), "width": rng.uniform(0.02, 0.04),
            "height": rng.uniform(0.006, 0.012), "wall": rng.uniform(0.0015, 0.003)}


def _goblet_lines(p):
    """(inside point, outside point) pairs in the part frame, on lines normal to a wall."""
    height = p["inner_height"] + p["wall"]
    slope = (p["top_radius"] - p["bottom_radius"]) / height
    inset = p["wall"] * math.hypot(1, slope)
    normal = np.array([1.0, -slope]) / math.hypot(1, slope)  # (radial, z), outward
    lines = [((0, 0, p["wall"] + 0.004), (0, 0, -0.004))]  # the bottom
    for f, angle in ((0.35, 0.0), (0.55, math.pi / 32), (0.7, 2.0)):
        z = p["wall"] + f * p["inner_height"]
        mid = np.array([p["bottom_radius"] + slope * z - inset / 2, z])
        radial = np.array([math.cos(angle), math.sin(angle), 0.0])
        ends = []
        for sign in (-1, 1):
            r, zz = mid + sign * (p["wall"] / 2 + 0.003) * normal
            ends.append(tuple(r * radial + [0, 0, zz]))
        lines.append(tuple(ends))
    return lines


def _box_lines(p, groove: bool):
    """Lines through the walls of an open box or a track (centred bounding box)."""
    t, d = p["wall"], 0.001 if groove else 0.003
    low = -p["height"] / 2
    z = low + t + (2 * (p["height"] - t) / 3 if groove else (p["height"] - t) / 2)
    lines = [((0, 0, low + t + d), (0, 0, low - 0.003))]
    for axis, size in ((1, p["width"]), *(((0, p["length"]),) if not groove else ())):
        for sign in (-1, 1):
            inner, outer = np.zeros(3), np.zeros(3)
            inner[2] = outer[2] = z
            inner[axis] = sign * (size / 2 - t - d)
            outer[axis] = sign * (size / 2 + 0.003)
            lines.append((tuple(inner), tuple(outer)))
    return lines


FAMILIES = {"goblet": (_goblet, _goblet_lines), "open_box": (_open_box, lambda p: _box_lines(p, False)),
            "track": (_track, lambda p: _box_lines(p, True))}
POSES = ({}, {"heading": 37.0, "pitch": 21.0, "roll": -13.0}, {"heading": -90.0, "roll": 90.0})


def _objects(family: str, params: dict, kind: str, pose: dict) -> tuple[dict, list]:
    """Objects and joints: body ``a`` of the family, free, welded or hinged."""
    a = {"part": family, "params": params, "mass": 0.05, "pose": {"z": 0.3, **pose}}
    if kind == "free":
        return {"a": a}, []
    if kind == "hinged":
        return {"a": a}, [{"kind": "hinge", "objects": ["a"], "point": [0.0, 0.0, 0.3],
                           "axis": [1, 0, 0]}]
    # welded to tracks far below it: more than 16 pieces, so boxes become hulls too
    track = {"part": "track", "params": {"length": 0.3, "width": 0.025, "height": 0.006,
                                         "wall": 0.003}, "mass": 0.02}
    others = {f"w{i}": {**track, "pose": {"x": 0.3, "y": 0.03 * i, "heading": 10.0 * i}}
              for i in range(6)}
    return {"a": a, **others}, [{"kind": "weld", "objects": ["a", w]} for w in others]


def _distance_to(meshes, points):
    """(n,) distances (m) from points (n, 3) outside them to the union of meshes."""
    return np.min([trimesh.proximity.closest_point_naive(m, points)[1] for m in meshes], axis=0)


def _hull_meshes(built):
    out = []
    for piece in built.pieces:
        frame = np.asarray(piece.frame, float)
        verts = hull_vertices(piece) @ frame[:3, :3].T + frame[:3, 3]
        hull = ConvexHull(verts)
        out.append(trimesh.Trimesh(verts, hull.simplices))
    return out


def measure(family: str, params: dict, kind: str, pose: dict):
    """Per probe line: (physics in, pieces in, physics out, pieces out, CAD in, CAD out, length)."""
    objects, joints = _objects(family, params, kind, pose)
    sc = tiny(objects, NEVER, joints=joints)
    scene = scene_of(sc)
    built = scene.bodies["a"].built
    lines = FAMILIES[family][1](params)
    inner = np.array([a for a, _ in lines], float)
    outer = np.array([b for _, b in lines], float)
    cad = trimesh.Trimesh(np.asarray(built.vertices), np.asarray(built.faces))
    pieces = _hull_meshes(built)
    out = []
    with World(scene, sc.settings) as world:
        world.step()  # a hinged link's collision shape is placed by the first step
        h, pose_now = world.handles["a"], world.pose("a")
        sphere = world.engine.createCollisionShape(pb.GEOM_SPHERE, radius=PROBE)

        def gap(point):
            at = pose_now[:3, :3] @ point + pose_now[:3, 3]
            probe = world.engine.createMultiBody(0.0, sphere, basePosition=at.tolist())
            found = pb.getClosestPoints(h.uid, probe, 0.02, h.link, -1, physicsClientId=world.cid)
            world.engine.removeBody(probe)
            return min(c[8] for c in found) + PROBE

        for a, b in zip(inner, outer, strict=True):
            out.append((gap(a), gap(b)))
    physics = np.array(out)
    return (physics, np.column_stack([_distance_to(pieces, inner), _distance_to(pieces, outer)]),
            np.column_stack([_distance_to([cad], inner), _distance_to([cad], outer)]),
            np.linalg.norm(outer - inner, axis=1))


def _example(family: str) -> dict:
    return params_dict(sys.modules[load_families()[family].params.__module__].EXAMPLE)


def _cases(n_params: int, kinds, poses):
    """Each family at its example parameters (parts other tests build too), then at
    ``n_params`` generated ones, as each kind of body in each pose."""
    rng = np.random.default_rng(RNG_SEED)
    cases = []
    for family, (draw, _) in FAMILIES.items():
        for i in range(n_params + 1):
            params = _example(family) if i == 0 else {
                k: round(v, 4) for k, v in draw(rng).items()}
            for kind in kinds:
                for j, pose in enumerate(poses):
                    cases.append(pytest.param(family, params, kind, pose,
                                              id=f"{family}{i}-{kind}-pose{j}"))
    return cases


def check(family, params, kind, pose):
    physics, pieces, cad, length = measure(family, params, kind, pose)
    face = np.abs(physics - pieces).max()
    assert face <= FACE_TOL, f"a face {face * 1e3:.3f} mm off the collision pieces"
    thickness = length - physics.sum(axis=1)
    wanted = length - cad.sum(axis=1)
    worst = np.abs(thickness - wanted).max()
    assert worst <= WALL_TOL, (f"walls {np.round(thickness * 1e3, 3)} mm in physics, "
                               f"{np.round(wanted * 1e3, 3)} mm in the CAD")


@pytest.mark.parametrize(("family", "params", "kind", "pose"),
                         _cases(0, ("free", "welded", "hinged"), POSES[1:2]))
def test_the_physics_sees_the_parts_walls(family, params, kind, pose):
    check(family, params, kind, pose)


@pytest.mark.slow
@pytest.mark.parametrize(("family", "params", "kind", "pose"),
                         _cases(4, ("free", "welded", "hinged"), POSES))
def test_the_physics_sees_the_parts_walls_generated(family, params, kind, pose):
    check(family, params, kind, pose)
