"""Supports for raised static parts (rgmcad.making): which parts are raised, the stands'
geometry, and that stands stay clear of moving bodies without changing outcomes."""

from functools import cache
from pathlib import Path

import numpy as np
import pytest

from rgmcad.making.clearance import ClearanceSettings, plan_supports
from rgmcad.making.placement import make_site
from rgmcad.making.stands import card_net, write_stand_files
from rgmcad.making.supports import base_planes, holdings, raised_parts
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario

ROOT = Path(__file__).resolve().parent.parent
SLOPE = ROOT / "tests" / "data" / "raised_slope.toml"


@cache
def _loaded(path, layout):
    scenario = load_scenario(path)
    parts = load_parts(scenario)
    values = resolve_layout(scenario, layout, None)[1]
    return scenario, parts, values


@cache
def _plan(path, layout, runs):
    scenario, parts, values = _loaded(path, layout)
    return plan_supports(scenario, values, parts, ClearanceSettings(runs=runs))


def _scene(path, layout="initial"):
    scenario, parts, values = _loaded(path, layout)
    return make_scene(scenario, values, parts)


def test_raised_parts_are_the_floating_static_ones():
    held = {h.part.name: h for h in holdings(_scene(SLOPE))}
    assert set(held) == {"track", "plank", "block"}  # the ball moves, the floor is a plane
    assert held["block"].held_by == "floor"
    assert held["track"].raised and held["plank"].raised
    assert held["plank"].gap == pytest.approx(0.05 - 0.5 * (0.1 * np.sin(np.radians(12))
                                                            + 0.006 * np.cos(np.radians(12))),
                                              abs=1e-4)


def test_a_hinged_parts_base_and_a_touching_part_count():
    held = {h.part.name: h for h in holdings(_scene(ROOT / "scenarios" / "branching.toml",
                                                    "solved"))}
    assert held["lever"].part.bodies == ("lever.axle",)  # the fixed base, not the plank
    assert held["lever"].raised
    assert held["track"].held_by == "part support"  # resting on a held part


def test_a_layout_without_planes_is_built_against_a_virtual_board():
    (plane,) = base_planes(_scene(ROOT / "scenarios" / "teapot.toml", "solved"))
    assert plane.virtual and plane.normal.tolist() == [0.0, -1.0, 0.0]


def test_stand_meets_the_tilted_face_and_rests_flat():
    scene = _scene(SLOPE)
    for holding in raised_parts(scene):
        (stand, *_) = make_site(scene, holding).choose(1)
        mesh = stand.mesh()
        assert mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0
        base = stand.footprint()
        assert np.allclose(base[:, 2], 0.0, atol=1e-9)  # flat on the floor
        assert np.allclose(mesh.face_normals[:2], [0, 0, -1])
        body = scene.bodies[holding.part.bodies[0]]
        top = stand.vertices()[4:]
        n = np.cross(top[1] - top[0], top[3] - top[0])
        n /= np.linalg.norm(n)
        above = (body.world_vertices() - top[0]) @ n
        assert above.min() == pytest.approx(0.0, abs=2e-4)  # touches the part's face ...
        assert above.min() > -2e-4  # ... and stays under it
    assert {round(s.tilt_deg) for h in raised_parts(scene)
            for s in make_site(scene, h).choose(1)} == {25, 12}


def test_card_net_strip_is_the_perimeter():
    scene = _scene(SLOPE)
    (stand, *_) = make_site(scene, raised_parts(scene)[0]).choose(1)
    kind, strip = card_net(stand)[0]
    length, width = stand.size
    assert kind == "cut" and np.allclose(strip[0], strip[-1])
    assert strip[:, 0].max() == pytest.approx(2000 * (length + width) + 8.0)


@pytest.mark.parametrize("path, layout", [(SLOPE, "initial"),
                                          (ROOT / "scenarios" / "simple.toml", "solved")])
def test_stands_clear_of_moving_bodies_and_outcomes_unchanged(path, layout):
    plan = _plan(path, layout, 4)
    assert plan.raised and not plan.unsupported
    assert {s.part for s in plan.stands} == {h.part.name for h in plan.raised}
    assert len(plan.checks) == 5  # the nominal run and 4 perturbed runs
    assert not plan.touched
    assert not plan.changed


def test_stand_files(tmp_path):
    plan = _plan(SLOPE, "initial", 4)
    written = write_stand_files(plan.stands, tmp_path, step=False)
    import trimesh

    stl = trimesh.load(tmp_path / "S1.stl")
    assert stl.is_watertight
    assert stl.bounds[0, 2] == pytest.approx(0.0, abs=1e-6)  # world millimetres, on the floor
    assert {p.suffix for p in written} == {".stl", ".svg"}


@pytest.mark.slow
def test_cadquery_solid_is_the_mesh(tmp_path):
    import trimesh

    plan = _plan(SLOPE, "initial", 4)
    write_stand_files(plan.stands, tmp_path)
    import cadquery as cq

    for stand in plan.stands:
        shape = cq.importers.importStep(str(tmp_path / f"{stand.label}.step")).val()
        assert shape.Volume() == pytest.approx(stand.mesh().volume * 1e9, rel=1e-6)
        cq.exporters.export(shape, str(tmp_path / "cq.stl"))
        mesh = trimesh.load(tmp_path / "cq.stl")
        assert mesh.is_watertight
        assert mesh.bounds[0, 2] == pytest.approx(0.0, abs=1e-3)


@pytest.mark.slow
def test_cli_supports_writes_stands_and_a_template(tmp_path):
    from tests._support import cli_output, run_cli

    code, doc = run_cli(["supports", str(SLOPE), "--out", str(tmp_path), "--runs", "1",
                         "--no-step", "--json"])
    assert code == 0 and doc["runs"] == 2 and doc["runs_touched"] == 0
    assert {s["part"] for s in doc["stands"]} == {"track", "plank"}
    names = {Path(p).name for p in doc["files"]}
    assert {"S1.stl", "S1-card.svg", "template.pdf", "template.svg"} <= names
    svg = (tmp_path / "template" / "template.svg").read_text()
    assert "S1 support of track" in svg  # the footprint's label on the sheets
    from tests.test_bom import pdf_text

    text = pdf_text(tmp_path / "template")  # the template `rgmcad template` makes, stands in
    bill = next(t for t in text if "bill of materials" in t)
    steps = "".join(t for t in text if "assembly steps" in t)
    assert "S1" in bill and "S1" in steps and steps.index("S1") < steps.index("track")
    from rgmcad.making.stands import read_stands

    stands = read_stands(tmp_path / "supports.json")  # round trip
    assert [s.footprint().round(6).tolist() for s in stands] == \
        [s["footprint_world"] for s in doc["stands"]]
    code, out, _ = cli_output(["export", str(SLOPE), "--out", str(tmp_path / "a.step"),
                               "--supports", str(tmp_path / "supports.json")])
    assert code == 0 and f"and {len(stands)} stands" in out


def test_cli_supports_refuses_bad_input_in_one_line(tmp_path):
    from tests._support import cli_output

    code, _, err = cli_output(["supports", str(SLOPE), "--out", str(tmp_path), "--runs", "x"])
    assert code == 2 and "--runs" in err and "Traceback" not in err
    bad = tmp_path / "bad.json"
    bad.write_text("{}")
    code, _, err = cli_output(["export", str(SLOPE), "--out", str(tmp_path / "a.step"),
                               "--supports", str(bad)])
    assert code == 2 and "--supports" in err and len(err.strip().splitlines()) == 1


def test_report_has_a_supports_section():
    from rgmcad.runs.supports_text import supports_lines

    doc = _plan(SLOPE, "initial", 4).to_json()
    text = "\n".join(supports_lines(doc))
    assert "## Supports" in text and "| S1 | " in text and "2 static parts are raised" in text
    assert supports_lines(None) == []


def test_a_lever_axle_over_a_shelf_gets_a_post_against_its_end():
    from rgmcad.making.beside import side_sites

    scene = _scene(ROOT / "scenarios" / "branching.toml", "solved")
    (lever,) = raised_parts(scene)
    assert lever.base.name == "top of support"  # the held box under it, not the floor
    assert lever.gap == pytest.approx(0.011 - 0.0012, abs=1e-4)
    posts = [s for site in side_sites(scene, lever) for s in site.choose(1)]
    assert posts
    axle = scene.bodies["lever.axle"].world_vertices()
    for post in posts:
        mesh = post.mesh()
        assert mesh.is_watertight
        assert post.footprint()[:, 2] == pytest.approx(0.0)  # on the box's top, z = 0
        assert post.heights().min() > axle[:, 2].max() - 0.0  # up past the axle
        ends = np.abs(axle[:, 1] - post.vertices()[:, 1].min()).min(), \
            np.abs(axle[:, 1] - post.vertices()[:, 1].max()).min()
        assert min(ends) < 1e-6  # its side is against the axle's end


def test_an_axle_pointing_at_the_board_gets_posts_against_its_side_below_its_plank():
    from rgmcad.making.beside import POST, side_sites

    scene = _scene(ROOT / "scenarios" / "ballrun.toml", "solved")
    (lever,) = [h for h in raised_parts(scene) if h.part.name == "base_plank"]
    axle = scene.bodies["base_plank.axle"].world_vertices()
    plank = scene.bodies["base_plank"].world_vertices()
    assert axle[:, 1].min() > 0.003  # its end 3.75 mm off the board (y = 0): it floats
    posts = [s for site in side_sites(scene, lever) for s in site.choose(1)]
    assert len(posts) == 4  # one on each side of the axle
    for post in posts:
        v = post.vertices()
        assert post.mesh().is_watertight and v[:, 1].min() == pytest.approx(0.0, abs=1e-9)
        assert v[:, 1].max() > axle[:, 1].min() + 0.002  # up along the axle's end ...
        assert v[:, 1].max() < plank[:, 1].min() - POST.margin  # ... and clear of its plank
        gaps = [np.abs(axle[:, k][:, None] - v[:, k][None]).min() for k in (0, 2)]
        assert min(gaps) < 1e-6  # a side against the axle's side
        inside = [np.all((axle[:, k].min() < v[:, k]) & (v[:, k] < axle[:, k].max()))
                  for k in (0, 2)]
        assert not any(inside)  # beside the axle, not through it


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ballrun", "long_chain"])
def test_every_raised_part_of_a_shipped_layout_gets_an_untouched_stand(name):
    plan = _plan(ROOT / "scenarios" / f"{name}.toml", "solved", 2)
    assert plan.raised and not plan.unsupported
    assert {s.part for s in plan.stands} == {h.part.name for h in plan.raised}
    assert not plan.touched
