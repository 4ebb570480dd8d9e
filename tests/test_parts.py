"""Conformance suite over the part registry: every family builds into a sound part.

Each family module exposes ``EXAMPLE``, a representative parameter set; every check below runs
on every family, so a new family file is tested by adding it.
"""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
import textwrap

import manifold3d
import numpy as np
import pytest
import trimesh
from scipy.spatial import ConvexHull

from rgmcad.errors import ScenarioError
from rgmcad.geometry import pose_matrix
from rgmcad.parts import build
from rgmcad.parts.family import MAIN, load_families, params_dict
from rgmcad.parts.pieces import (
    BoxPiece,
    CapsulePiece,
    ConvexPiece,
    CylinderPiece,
    PlanePiece,
    SpherePiece,
    piece_from_dict,
)

FAMILIES = load_families()
NAMES = sorted(FAMILIES)
SOLIDS = [name for name in NAMES if not FAMILIES[name].infinite]

COVER_TOLERANCE = 2e-4  # m: every surface point lies this close to some collision piece
VOLUME_TOLERANCE = 0.005  # relative: mesh and CAD volume against the analytic one


def example(family):
    return sys.modules[family.params.__module__].EXAMPLE


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    out = tmp_path_factory.mktemp("parts")
    return {name: build.build_part(FAMILIES[name], example(FAMILIES[name]), out) for name in NAMES}


# --- geometry helpers -------------------------------------------------------------------------


def _local(points: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """(n, 3) points of the part frame expressed in a piece's frame."""
    return (points - frame[:3, 3]) @ frame[:3, :3]


def distance_to_piece(points: np.ndarray, piece) -> np.ndarray:
    """(n,) distance from each point to a convex piece (0 inside).

    Convex hulls give the largest distance to their face planes: exact when the nearest point
    is on a face, a lower bound near edges.
    """
    q = _local(points, piece.frame)
    if isinstance(piece, BoxPiece):
        outside = np.abs(q) - np.asarray(piece.size) / 2
        return np.linalg.norm(np.maximum(outside, 0), axis=1)
    if isinstance(piece, SpherePiece):
        return np.maximum(np.linalg.norm(q, axis=1) - piece.radius, 0)
    if isinstance(piece, CylinderPiece):
        radial = np.hypot(q[:, 0], q[:, 1]) - piece.radius
        axial = np.abs(q[:, 2]) - piece.height / 2
        return np.hypot(np.maximum(radial, 0), np.maximum(axial, 0))
    if isinstance(piece, CapsulePiece):
        along = np.clip(q[:, 2], -piece.length / 2, piece.length / 2)
        return np.maximum(np.hypot(np.hypot(q[:, 0], q[:, 1]), q[:, 2] - along) - piece.radius, 0)
    if isinstance(piece, ConvexPiece):
        equations = ConvexHull(piece.vertices).equations
        return np.maximum((q @ equations[:, :3].T + equations[:, 3]).max(axis=1), 0)
    raise TypeError(piece)


def piece_corners(piece) -> np.ndarray:
    """(n, 3) points in the part frame whose bounding box is the piece's bounding box."""
    frame = piece.frame
    if isinstance(piece, BoxPiece):
        signs = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        local = signs * np.asarray(piece.size) / 2
    elif isinstance(piece, SpherePiece):
        local = np.vstack([np.eye(3), -np.eye(3)]) * piece.radius
        frame = frame.copy()
        frame[:3, :3] = np.eye(3)  # a sphere's box does not turn with it
    elif isinstance(piece, CylinderPiece):
        axis = frame[:3, 2]
        half = np.abs(axis) * piece.height / 2 + piece.radius * np.sqrt(np.clip(1 - axis**2, 0, 1))
        centre = frame[:3, 3]
        return np.array([centre - half, centre + half])
    elif isinstance(piece, CapsulePiece):
        axis, centre = frame[:3, 2] * piece.length / 2, frame[:3, 3]
        return np.array([centre - np.abs(axis) - piece.radius, centre + np.abs(axis) + piece.radius])
    else:
        local = np.asarray(piece.vertices)
    return local @ frame[:3, :3].T + frame[:3, 3]


def piece_manifold(piece) -> manifold3d.Manifold:
    if isinstance(piece, BoxPiece):
        solid = manifold3d.Manifold.cube(tuple(piece.size), center=True)
    elif isinstance(piece, SpherePiece):
        solid = manifold3d.Manifold.sphere(piece.radius, circular_segments=256)
    elif isinstance(piece, CylinderPiece):
        solid = manifold3d.Manifold.cylinder(piece.height, piece.radius, piece.radius,
                                             circular_segments=256, center=True)
    elif isinstance(piece, CapsulePiece):
        ball = manifold3d.Manifold.sphere(piece.radius, circular_segments=256)
        solid = manifold3d.Manifold.batch_hull([ball.translate((0, 0, -piece.length / 2)),
                                                ball.translate((0, 0, piece.length / 2))])
    else:
        solid = manifold3d.Manifold.hull_points(np.asarray(piece.vertices, float))
    return solid.transform(np.asarray(piece.frame, float)[:3, :4])


def mesh_manifold(body) -> manifold3d.Manifold:
    mesh = manifold3d.Mesh(vert_properties=body.vertices.astype(np.float32),
                           tri_verts=body.faces.astype(np.uint32))
    return manifold3d.Manifold(mesh)


def bodies(built, name):
    return list(built[name].bodies.values())


# --- the family modules -----------------------------------------------------------------------


@pytest.mark.parametrize("name", NAMES)
def test_family_declares_its_contract(name):
    family = FAMILIES[name]
    module = sys.modules[family.params.__module__]
    assert family.description and "\n" not in family.description
    assert dataclasses.is_dataclass(family.params) and family.params.__dataclass_params__.frozen
    params = example(family)
    assert isinstance(params, family.params)
    assert getattr(params, "check", lambda: None)() is None
    assert "Frame" in (module.__doc__ or ""), "the module docstring must say where the origin is"
    assert (family.build is None) == family.infinite
    if not family.infinite:
        assert family.volume is not None and family.volume(params) > 0
    # The parameters survive a round trip through a scenario file's mapping.
    again = family.make_params(params_dict(params))
    assert build.part_id(family, again) == build.part_id(family, params)


def test_family_modules_do_not_import_cadquery():
    code = textwrap.dedent("""
        import sys
        from rgmcad.parts.family import load_families
        families = load_families()
        for f in families.values():
            mod = sys.modules[f.params.__module__]
            f.collision_pieces(mod.EXAMPLE), f.joints(mod.EXAMPLE)
        assert "cadquery" not in sys.modules, "a family imports cadquery at module level"
    """)
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.mark.parametrize(
    "name, values",
    [
        ("ball", {"radius": -0.01}),
        ("ball", {"radius": "big"}),
        ("ball", {}),
        ("box", {"length": 0.1, "width": 0.0, "height": 0.1}),
        ("box", {"length": 0.1, "width": 0.1, "height": 0.1, "depth": 0.1}),
        ("cylinder", {"radius": -1.0, "height": 0.1}),
        ("track", {"length": 0.3, "width": 0.02, "height": 0.01, "wall": 0.01}),
        ("track", {"length": 0.3, "width": 0.02, "height": 0.01, "wall": 0.011}),
        ("open_box", {"length": 0.1, "width": 0.1, "height": 0.01, "wall": 0.01}),
        ("goblet", {"inner_height": 0.1, "top_radius": 0.01, "bottom_radius": 0.01,
                    "wall": 0.011}),
        ("goblet", {"inner_height": 0.1, "top_radius": 0.03, "bottom_radius": 0.02,
                    "wall": 0.002, "sectors": 4}),
        ("goblet", {"inner_height": 0.1, "top_radius": 0.03, "bottom_radius": 0.02,
                    "wall": 0.002, "sectors": 32.5}),
        ("lever", {"length": 0.1, "width": 0.02, "thickness": -0.005}),
        ("lever", {"length": 0.1, "width": 0.02, "thickness": 0.005, "axle_radius": 0.0}),
        ("lever", {"length": 0.1, "width": 0.02, "thickness": 0.005, "axle_length": "long"}),
        ("plane", {"normal": [0, 0, 1]}),
    ],
)
def test_bad_params_raise_scenario_error(name, values):
    with pytest.raises(ScenarioError):
        FAMILIES[name].make_params(values, where="scene.toml", key="objects.thing")
    if values:
        with pytest.raises((ScenarioError, TypeError)):
            build.part_id(FAMILIES[name], values)


# --- built parts ------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SOLIDS)
def test_meshes_are_closed_and_small(built, name):
    part = built[name]
    assert next(iter(part.bodies)) == MAIN
    for body in part.bodies.values():
        assert body.vertices.dtype == np.float64 and body.vertices.shape[1] == 3
        assert body.faces.dtype == np.int64 and body.faces.shape[1] == 3
        mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
        assert mesh.is_watertight, body.key
        assert mesh.is_winding_consistent, body.key
        assert mesh.volume > 0, "normals must point outward"
        assert len(body.faces) <= 5000, "meshes feed manifold3d intersection tests: keep small"
        assert np.all(body.vertices >= body.bbox[0] - 1e-9)
        assert np.all(body.vertices <= body.bbox[1] + 1e-9)


@pytest.mark.parametrize("name", SOLIDS)
def test_volumes_match_the_analytic_volume(built, name):
    family = FAMILIES[name]
    analytic = family.volume(example(family))
    for body in bodies(built, name):
        mesh_volume = trimesh.Trimesh(body.vertices, body.faces, process=False).volume
        expected = analytic if body.key == MAIN else body.volume
        assert body.volume == pytest.approx(expected, rel=VOLUME_TOLERANCE)
        assert mesh_volume == pytest.approx(expected, rel=VOLUME_TOLERANCE)
    assert built[name].main.volume == pytest.approx(analytic, rel=1e-9), "OCC volume is exact"


@pytest.mark.parametrize("name", SOLIDS)
def test_mass_properties_are_physical(built, name):
    for body in bodies(built, name):
        density = 1000.0
        mass = density * body.volume
        assert mass > 0
        inertia = body.inertia(mass)
        np.testing.assert_allclose(inertia, inertia.T, atol=1e-12 * np.abs(inertia).max())
        principal = np.linalg.eigvalsh(inertia)
        assert principal.min() > 0
        # The triangle inequality of principal moments holds for every real body.
        assert principal[0] + principal[1] >= principal[2] * (1 - 1e-9)
        assert np.all(body.centre_of_mass >= body.bbox[0]) and np.all(
            body.centre_of_mass <= body.bbox[1])
        mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
        size = np.max(body.bbox[1] - body.bbox[0])
        np.testing.assert_allclose(mesh.center_mass, body.centre_of_mass, atol=2e-3 * size)
        np.testing.assert_allclose(mesh.moment_inertia, body.inertia_unit,
                                   atol=0.02 * np.abs(body.inertia_unit).max())


CHORDS = {"goblet": 1e-4}
"""m: families whose pieces' flat faces stand for curved ones, each face half-way between the
chord and the tangent (parts/goblet.py), so up to this far outside the solid."""


@pytest.mark.parametrize("name", SOLIDS)
def test_pieces_lie_inside_the_bounding_box(built, name):
    reach = CHORDS.get(name, 1e-6)
    for body in bodies(built, name):
        assert body.pieces
        for piece in body.pieces:
            assert not isinstance(piece, PlanePiece)
            corners = piece_corners(piece)
            assert np.all(corners >= body.bbox[0] - reach), piece
            assert np.all(corners <= body.bbox[1] + reach), piece


@pytest.mark.parametrize("name", SOLIDS)
def test_pieces_cover_the_surface(built, name):
    rng = np.random.default_rng(0)
    for body in bodies(built, name):
        mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
        samples, _ = trimesh.sample.sample_surface(mesh, 3000, seed=rng.integers(2**31))
        points = np.vstack([samples, body.vertices])
        distance = np.min([distance_to_piece(points, p) for p in body.pieces], axis=0)
        worst = int(np.argmax(distance))
        assert distance[worst] <= COVER_TOLERANCE, f"{body.key!r}: {points[worst]} is uncovered"


@pytest.mark.parametrize("name", SOLIDS)
def test_pieces_stay_inside_the_solid_and_do_not_overlap(built, name):
    for body in bodies(built, name):
        solid = mesh_manifold(body)
        pieces = [piece_manifold(p) for p in body.pieces]
        for piece, shape in zip(body.pieces, pieces, strict=True):
            inside = (shape ^ solid).volume()
            assert inside >= 0.98 * shape.volume(), f"{body.key!r}: {piece} sticks out"
        union = manifold3d.Manifold.batch_boolean(pieces, manifold3d.OpType.Add)
        total = sum(s.volume() for s in pieces)
        assert union.volume() == pytest.approx(total, rel=1e-6), "collision pieces overlap"
        assert total == pytest.approx(body.volume, rel=0.1)


@pytest.mark.parametrize("name", SOLIDS)
def test_box_tilings_have_the_exact_mass_properties(built, name):
    """Where the pieces are boxes that tile the solid, they give its volume and inertia."""
    for body in bodies(built, name):
        if not all(isinstance(p, BoxPiece) for p in body.pieces):
            continue
        volume, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
        for piece in body.pieces:
            size = np.asarray(piece.size)
            v = np.prod(size)
            rot, centre = piece.frame[:3, :3], piece.frame[:3, 3]
            own = rot @ np.diag(v * size**2 / 12) @ rot.T  # sum of x x^T about its centre
            volume += v
            first += v * centre
            second += own + v * np.outer(centre, centre)
        com = first / volume
        covariance = second - volume * np.outer(com, com)
        inertia = np.trace(covariance) * np.eye(3) - covariance
        assert volume == pytest.approx(body.volume, rel=1e-9)
        np.testing.assert_allclose(com, body.centre_of_mass, atol=1e-12)
        np.testing.assert_allclose(inertia, body.inertia_unit,
                                   atol=1e-9 * np.abs(inertia).max())


@pytest.mark.parametrize("name", SOLIDS)
def test_files_and_joints(built, name):
    part = built[name]
    assert set(part.files) == {"step", "stl", "glb"}
    for path in part.files.values():
        assert path.is_file() and path.stat().st_size > 0
    for hinge in part.joints:
        assert hinge.moving in part.bodies and hinge.fixed in part.bodies
        assert hinge.moving != hinge.fixed
        assert np.linalg.norm(hinge.axis) == pytest.approx(1)
    for key, body in part.bodies.items():
        assert body.fixed == (key != MAIN)
    assert FAMILIES[name].fixed_bodies(example(FAMILIES[name])) == tuple(
        k for k in part.bodies if k != MAIN)


def test_plane_is_infinite_and_turns_into_a_back_board(built):
    part = built["plane"]
    assert part.infinite and part.bodies == {} and part.files == {} and part.joints == ()
    family = FAMILIES["plane"]
    (piece,) = family.collision_pieces(example(family))[MAIN]
    assert isinstance(piece, PlanePiece)
    normal = pose_matrix([0, 0, 0, 0, -90, 0])[:3, :3] @ piece.frame[:3, 2]
    np.testing.assert_allclose(normal, [0, 1, 0], atol=1e-12)


def test_lever_hinge_runs_along_the_axle(built):
    part = built["lever"]
    params = example(FAMILIES["lever"])
    (hinge,) = part.joints
    assert (hinge.moving, hinge.fixed) == (MAIN, "axle")
    axle = part.bodies["axle"]
    np.testing.assert_allclose(axle.centre_of_mass, hinge.point, atol=1e-12)
    (piece,) = axle.pieces
    np.testing.assert_allclose(piece.frame[:3, 2], hinge.axis, atol=1e-12)
    np.testing.assert_allclose(axle.bbox[1] - axle.bbox[0],
                               [2 * params.axle_radius, params.axle_length,
                                2 * params.axle_radius], atol=1e-9)
    assert params.axle_length == pytest.approx(params.width + 0.01)


@pytest.mark.parametrize("name", NAMES)
def test_pieces_survive_their_dict_form(name):
    family = FAMILIES[name]
    for pieces in family.collision_pieces(example(family)).values():
        for piece in pieces:
            data = piece.to_dict()
            again = piece_from_dict(json.loads(json.dumps(data)))
            assert type(again) is type(piece) and again.to_dict() == data
    with pytest.raises(ValueError, match="allowed: box, sphere"):
        piece_from_dict({"kind": "cone", "frame": np.eye(4).tolist()})
