"""The build pipeline: golden mass properties, the on-disk cache, loading without CadQuery."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap
from dataclasses import dataclass

import numpy as np
import pytest
import trimesh

from rgmcad.errors import ScenarioError
from rgmcad.parts import build
from rgmcad.parts.family import Family, load_families
from rgmcad.parts.pieces import ConvexPiece
from rgmcad.parts.store import PartStore

FAMILIES = load_families()


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    return tmp_path_factory.mktemp("built")


def make(name: str, **values):
    return FAMILIES[name].make_params(values)


def built(name: str, out, **values) -> build.BuiltPart:
    return build.load_part(FAMILIES[name], make(name, **values), out)


# --- golden numbers against closed forms ------------------------------------------------------


def test_box_1x2x3(out):
    body = built("box", out, length=1.0, width=2.0, height=3.0).main
    mass = 6.0  # density 1
    assert body.volume == pytest.approx(6.0, rel=1e-12)
    np.testing.assert_allclose(body.centre_of_mass, 0, atol=1e-12)
    expected = np.diag([mass * (4 + 9) / 12, mass * (1 + 9) / 12, mass * (1 + 4) / 12])
    np.testing.assert_allclose(body.inertia_unit, expected, atol=1e-12)
    np.testing.assert_allclose(body.inertia(mass=12.0), 2 * expected, atol=1e-12)
    np.testing.assert_allclose(body.bbox, [[-0.5, -1, -1.5], [0.5, 1, 1.5]], atol=1e-12)
    assert len(body.faces) == 12


def test_ball(out):
    r = 0.02
    body = built("ball", out, radius=r).main
    volume = 4 / 3 * math.pi * r**3
    assert body.volume == pytest.approx(volume, rel=1e-9)
    np.testing.assert_allclose(body.inertia_unit, np.eye(3) * 2 / 5 * volume * r**2, rtol=1e-9,
                               atol=1e-20)
    np.testing.assert_allclose(body.centre_of_mass, 0, atol=1e-12)


def test_cylinder(out):
    r, h = 0.01, 0.05
    body = built("cylinder", out, radius=r, height=h).main
    mass = math.pi * r**2 * h
    assert body.volume == pytest.approx(mass, rel=1e-9)
    side = mass * (3 * r**2 + h**2) / 12
    np.testing.assert_allclose(body.inertia_unit, np.diag([side, side, mass * r**2 / 2]),
                               rtol=1e-9, atol=1e-20)
    np.testing.assert_allclose(body.bbox, [[-r, -r, -h / 2], [r, r, h / 2]], atol=1e-12)


def test_goblet_with_straight_walls_is_a_tube_on_a_disc(out):
    # With equal radii the cavity is a cylinder of radius R - wall, floor at z = wall.
    R, h, t = 0.03, 0.08, 0.003
    body = built("goblet", out, inner_height=h, top_radius=R, bottom_radius=R, wall=t).main
    outer, inner = math.pi * R**2 * (h + t), math.pi * (R - t) ** 2 * h
    assert body.volume == pytest.approx(outer - inner, rel=1e-9)
    com_z = (outer * (h + t) / 2 - inner * (t + h / 2)) / (outer - inner)
    np.testing.assert_allclose(body.centre_of_mass, [0, 0, com_z], atol=1e-9)
    np.testing.assert_allclose(body.bbox, [[-R, -R, 0], [R, R, h + t]], atol=1e-9)


def test_goblet_wall_is_wall_thick_normal_to_the_cone(out):
    p = make("goblet", inner_height=0.1, top_radius=0.04, bottom_radius=0.02, wall=0.002)
    family = FAMILIES["goblet"]
    body = build.load_part(family, p, out).main
    assert body.volume == pytest.approx(family.volume(p), rel=1e-9)
    # Cut the mesh at mid-height: the section is two circles (polygons inscribed in them,
    # whose largest radii are exact), wall / cos(lean) apart.
    mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
    section = mesh.section(plane_origin=[0, 0, 0.05], plane_normal=[0, 0, 1])
    radii = np.linalg.norm(section.vertices[:, :2], axis=1)
    outer = radii[radii > radii.mean()]
    inner = radii[radii <= radii.mean()]
    lean = math.atan2(0.04 - 0.02, 0.102)
    assert outer.max() == pytest.approx(0.02 + 0.02 * 0.05 / 0.102, rel=1e-4)
    assert outer.max() - inner.max() == pytest.approx(0.002 / math.cos(lean), rel=0.01)


def test_lever_bodies(out):
    part = built("lever", out, length=0.2, width=0.02, thickness=0.01, pivot_x=0.03,
                 axle_radius=0.003)
    assert list(part.bodies) == ["", "axle"]
    plank, axle = part.bodies[""], part.bodies["axle"]
    assert not plank.fixed and axle.fixed
    assert plank.volume == pytest.approx(0.2 * 0.02 * 0.01, rel=1e-12)
    length = 0.03  # width + 10 mm
    mass = math.pi * 0.003**2 * length
    assert axle.volume == pytest.approx(mass, rel=1e-9)
    np.testing.assert_allclose(axle.centre_of_mass, [0.03, 0, 0], atol=1e-12)
    side = mass * (3 * 0.003**2 + length**2) / 12
    np.testing.assert_allclose(axle.inertia_unit, np.diag([side, mass * 0.003**2 / 2, side]),
                               rtol=1e-9, atol=1e-20)
    (hinge,) = part.joints
    assert hinge.point == (0.03, 0.0, 0.0) and hinge.axis == (0.0, 1.0, 0.0)


def test_files_are_in_the_documented_units(out):
    part = built("box", out, length=0.01, width=0.02, height=0.03)
    stl = trimesh.load(part.files["stl"])
    np.testing.assert_allclose(sorted(stl.extents), [10, 20, 30], rtol=1e-6)  # mm
    glb = trimesh.load(part.files["glb"])
    np.testing.assert_allclose(sorted(glb.extents), [0.01, 0.02, 0.03], rtol=1e-6)  # m
    text = part.files["step"].read_text()
    assert "MILLI" in text and "FILE_SCHEMA" in text


# --- identity and cache -----------------------------------------------------------------------


def test_part_id_depends_on_params_only_through_their_values():
    box = FAMILIES["box"]
    a = build.part_id(box, {"length": 1, "width": 2.0, "height": 3.0})
    assert a == build.part_id(box, box.params(1.0, 2.0, 3.0))
    assert a.startswith("box-") and len(a) == len("box-") + 12
    assert a != build.part_id(box, {"length": 1.0, "width": 2.0, "height": 3.5})
    lever = FAMILIES["lever"]
    default = {"length": 0.1, "width": 0.02, "thickness": 0.005}
    assert build.part_id(lever, default) == build.part_id(lever, {**default, "axle_length": 0.03})
    assert build.part_id(lever, {**default, "pivot_x": -0.0}) == build.part_id(lever, default)
    assert build.part_id(box, {"length": 1, "width": 2, "height": 3}) != build.part_id(
        FAMILIES["open_box"], {"length": 1, "width": 2, "height": 3, "wall": 0.1})


def test_build_parts_builds_once_and_then_reuses(tmp_path):
    box, ball = FAMILIES["box"], FAMILIES["ball"]
    instances = [(box, {"length": 0.1, "width": 0.02, "height": 0.005}),
                 (ball, {"radius": 0.01}),
                 (box, box.params(0.1, 0.02, 0.005))]
    calls = []
    store = PartStore(tmp_path)
    first = build.build_parts(instances, store, progress=lambda *a: calls.append(a))
    assert [c[:2] for c in calls] == [(1, 2), (2, 2)] and not any(c[3] for c in calls)
    assert [c[2] for c in calls] == [p.id for p in first]
    stamp = (tmp_path / first[0].id / "part.json").stat().st_mtime_ns

    store.forget()
    calls.clear()
    again = build.build_parts(instances, store, progress=lambda *a: calls.append(a))
    assert all(c[3] for c in calls), "second build must come from the cache"
    assert [p.id for p in again] == [p.id for p in first]
    assert (tmp_path / first[0].id / "part.json").stat().st_mtime_ns == stamp
    np.testing.assert_array_equal(again[1].main.vertices, first[1].main.vertices)

    calls.clear()
    forced = build.build_parts(instances[:1], store, force=True,
                               progress=lambda *a: calls.append(a))
    assert calls == [(1, 1, first[0].id, False)] and forced[0].id == first[0].id

    manifest = json.loads((tmp_path / "manifest.json").read_text())
    (entry,) = manifest["parts"]  # the manifest lists the last call's parts
    assert entry["id"] == first[0].id and entry["family"] == "box"
    assert entry["bodies"][""]["volume"] == pytest.approx(0.1 * 0.02 * 0.005)
    for name in entry["files"].values():
        assert (tmp_path / name).is_file()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")], "temp files left"


def test_load_part_caches_and_can_refuse_to_build(tmp_path):
    box = FAMILIES["box"]
    params = box.params(0.05, 0.05, 0.05)
    store = PartStore(tmp_path)
    with pytest.raises(FileNotFoundError):
        build.load_part(box, params, store, build_missing=False)
    part = build.load_part(box, params, store)
    assert build.load_part(box, params, store) is part
    assert build.load_part(box, {"length": 0.05, "width": 0.05, "height": 0.05}, store) is part
    store.forget()
    again = build.load_part(box, params, store, build_missing=False)
    assert again is not part and again.id == part.id
    np.testing.assert_array_equal(again.main.faces, part.main.faces)
    assert build.load_part(box, params, tmp_path) is not again, "a folder is a new store"


def test_a_forced_rebuild_replaces_the_part_the_store_remembers(tmp_path):
    box = FAMILIES["box"]
    store = PartStore(tmp_path)
    part = build.load_part(box, box.params(0.05, 0.05, 0.05), store)
    (rebuilt,) = build.build_parts([(box, box.params(0.05, 0.05, 0.05))], store, force=True)
    assert rebuilt is not part and rebuilt.id == part.id
    assert build.load_part(box, box.params(0.05, 0.05, 0.05), store) is rebuilt


def test_load_part_does_not_import_cadquery(out):
    families = [("goblet", {"inner_height": 0.11, "top_radius": 0.036,
                            "bottom_radius": 0.025, "wall": 0.002}),
                ("lever", {"length": 0.1, "width": 0.02, "thickness": 0.005}),
                ("plane", {})]
    build.build_parts([(FAMILIES[n], v) for n, v in families], out)
    code = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        from rgmcad.parts.build import load_part
        from rgmcad.parts.family import load_families
        families = load_families()
        for name, values in {families!r}:
            part = load_part(families[name], values, Path({str(out)!r}), build_missing=False)
            assert part.family == name
        assert "cadquery" not in sys.modules and "OCP" not in sys.modules
    """)
    subprocess.run([sys.executable, "-c", code], check=True)


def test_bad_params_raise_scenario_error(tmp_path):
    with pytest.raises(ScenarioError, match="radius"):
        build.build_part(FAMILIES["ball"], {"radius": -1.0}, tmp_path)
    with pytest.raises(ScenarioError, match="allowed: radius"):
        build.load_part(FAMILIES["ball"], {"radius": 1.0, "colour": "red"}, tmp_path)
    with pytest.raises(ScenarioError):
        build.build_part(FAMILIES["ball"], FAMILIES["ball"].params(radius=-1.0), tmp_path)
    assert list(tmp_path.iterdir()) == []


# --- families outside the registry ------------------------------------------------------------


@dataclass(frozen=True)
class Bracket:
    size: float = 0.04


def _bracket(p: Bracket):
    import cadquery as cq

    t = p.size / 4
    foot = cq.Solid.makeBox(p.size, t, t)
    leg = cq.Solid.makeBox(t, t, p.size)
    return foot.fuse(leg).clean()


def _broken(p: Bracket):
    raise RuntimeError("kernel failure")


def test_family_without_pieces_gets_a_convex_decomposition(tmp_path):
    family = Family(name="bracket", params=Bracket, build=_bracket, collision=None,
                    description="L bracket")
    part = build.build_part(family, Bracket(), tmp_path)
    body = part.main
    assert body.pieces and all(isinstance(p, ConvexPiece) for p in body.pieces)
    for piece in body.pieces:
        assert np.all(piece.vertices >= body.bbox[0]) and np.all(piece.vertices <= body.bbox[1])
    hull_volume = sum(trimesh.convex.convex_hull(p.vertices).volume for p in body.pieces)
    assert hull_volume == pytest.approx(body.volume, rel=0.25)
    assert json.loads((tmp_path / part.id / "part.json").read_text())["bodies"][""][
        "collision"] == "decomposed"


def test_failed_build_leaves_nothing_behind(tmp_path):
    family = Family(name="broken", params=Bracket, build=_broken, collision=None)
    with pytest.raises(RuntimeError, match="kernel failure"):
        build.build_part(family, Bracket(), tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_build_is_quiet(tmp_path, capfd):
    build.build_part(FAMILIES["cylinder"], {"radius": 0.01, "height": 0.01}, tmp_path)
    captured = capfd.readouterr()
    assert captured.out == "" and captured.err == ""
