"""What a template's words and arrows tell the maker: labels that stay whole on one sheet,
tilt and fall directions, tolerances that say what they are, a frame's tolerance once."""

from __future__ import annotations

import math
import re

import numpy as np
import pypdfium2 as pdfium
import pytest
import trimesh
from shapely.geometry import LineString
from shapely.geometry import box as shapely_box

from rgmcad.printing.inputs import BasePlane, PlacedPart, format_tolerance, template_inputs
from rgmcad.printing.seams import seams_of
from rgmcad.printing.template import make_template, scene_template
from rgmcad.printing.tiling import grid_size
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario

FLOOR = BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))


def _part(mesh, pose, name, order, fall=None):
    m = mesh.copy()
    m.apply_transform(pose)
    return PlacedPart(name, order, np.asarray(m.vertices), np.asarray(m.faces), pose, (),
                      None if fall is None else np.asarray(fall, float))


def _text(pdf_path, pages=None):
    doc = pdfium.PdfDocument(str(pdf_path))
    out = [doc[i].get_textpage().get_text_range() for i in range(len(doc))]
    doc.close()
    return out


def _kept_text(result) -> str:
    """The text a maker sees on the assembled sheets: each sheet's, within what it keeps."""
    pt = 72 / 25.4
    doc = pdfium.PdfDocument(str(result.pdf))
    out = []
    for s in result.sheets:
        (x0, y0), (x1, y1) = (s.to_page(s.keep_mm[0], s.keep_mm[3]),
                              s.to_page(s.keep_mm[2], s.keep_mm[1]))
        h = s.size_mm[1]
        out.append(doc[s.page - 1].get_textpage().get_text_bounded(
            x0 * pt, (h - y1) * pt, x1 * pt, (h - y0) * pt))
    doc.close()
    return " ".join(" ".join(out).split())


def _pose(rot=None, offset=(0, 0, 0)):
    m = np.eye(4)
    if rot is not None:
        m[:3, :3] = rot
    m[:3, 3] = offset
    return m


@pytest.fixture(scope="module")
def crowded(tmp_path_factory):
    """Dozens of blocks spread over several sheets, many near the seams."""
    rng = np.random.default_rng(3)
    parts = []
    for i in range(40):
        rz = trimesh.transformations.rotation_matrix(rng.uniform(0, np.pi), [0, 0, 1])[:3, :3]
        xy = rng.uniform([0, 0], [0.55, 0.5])
        parts.append(_part(trimesh.creation.box([0.03, 0.01, 0.02]),
                           _pose(rz, (*xy, 0.01)), f"block_with_a_long_name[{i}]", i + 1))
    return make_template(parts, [FLOOR], tmp_path_factory.mktemp("crowded"), paper="a4",
                         orientation="portrait")


def test_no_label_is_crossed_by_a_seam_or_left_where_no_sheet_keeps_it(crowded):
    r = crowded
    assert len(r.sheets) >= 4
    seams = seams_of(r.sheets)
    lines = [LineString([s.points(s.span[0]), s.points(s.span[1])]) for s in seams]
    for p in r.parts:
        label = shapely_box(*p.label_box)
        assert not any(label.intersects(ln) for ln in lines), p.name
        assert any(shapely_box(*s.keep_mm).contains(label) for s in r.sheets), p.name


def test_tilt_and_fall_directions_are_named(tmp_path):
    rx = trimesh.transformations.rotation_matrix(math.radians(15), [1, 0, 0])[:3, :3]
    parts = [
        # a plate whose top (local +z) leans towards world -y
        _part(trimesh.creation.box([0.06, 0.03, 0.01]), _pose(rx, (0.0, 0.0, 0.05)), "plate", 1),
        # a domino falling towards world +x (its local +X)
        _part(trimesh.creation.box([0.007, 0.02, 0.044]), _pose(None, (0.1, 0.0, 0.022)),
              "domino", 2, fall=(1.0, 0.0, 0.0)),
    ]
    r = make_template(parts, [FLOOR], tmp_path, paper="a4")
    plate, domino = r.parts
    assert any("leans towards world -y" in n for n in plate.notes), plate.notes
    assert any("falls towards world +x" in n for n in domino.notes), domino.notes
    text = " ".join(" ".join(_text(r.pdf)).split())
    assert "leans towards world -y" in text and "falls towards world +x" in text


def test_tolerances_say_when_the_model_shows_no_drop():
    # room to the range ends: 2 mm below, 5 mm above
    assert format_tolerance("y", "y", 0.001, 0.003, (0.002, 0.005)) == "y -1/+3 mm"
    assert format_tolerance("y", "y", 0.001, 0.005, (0.002, 0.005)) == (
        "y -1 mm (above: not limiting within the range)")
    assert format_tolerance("y", "y", 0.002, 0.005, (0.002, 0.005)) == (
        "y: not limiting within the range")
    assert format_tolerance("heading", "heading", 2.0, 2.0) == "heading ± 2°"


def test_a_run_frames_tolerance_is_stated_once_in_mm_at_its_far_end(tmp_path):
    scenario = load_scenario("scenarios/causality_switch.toml")
    _, values = resolve_layout(scenario, "solved", None)
    scene = make_scene(scenario, values, load_parts(scenario))
    low = {f.name: f.low for f in scenario.free}
    room = values[[f.name for f in scenario.free].index("switch_run.y")] - low["switch_run.y"]
    tol = {"switch_run.heading": (2.0, 2.0), "switch_run.y": (room, 0.004)}
    parts, _, frames = template_inputs(scenario, scene, tol)
    assert not any("heading" in t for p in parts for t in p.tolerances)  # not beside dominoes
    (note,) = [f for f in frames if f.name == "switch_run"]
    turn = next(n for n in note.notes if "far end" in n)
    mm, reach = float(turn.split("±")[1].split()[0]), float(turn.split(",")[1].split()[0])
    # the run's farthest domino, measured here from the scene itself
    origin = note.origin
    far = max(np.linalg.norm((b.world_vertices() - origin)[:, :2], axis=1).max()
              for b in scene.bodies.values() if b.object.startswith(("switch_run[", "wavey_run[",
                                                                     "straight_run[")))
    assert abs(reach - 1000 * far) < 1.0
    assert abs(mm - 1000 * far * math.radians(2.0)) < 0.2
    assert any("y +4 mm (below: not limiting within the range)" in n for n in note.notes)
    r = scene_template(scenario, scene, tmp_path, tolerances=tol)
    text = _kept_text(r)
    assert text.count("(heading ± 2°)") == 1


def test_every_sheet_keeps_world_coordinates_of_its_own(crowded):
    r = crowded
    pt = 72 / 25.4
    doc = pdfium.PdfDocument(str(r.pdf))
    for s in r.sheets:
        (x0, y0), (x1, y1) = (s.to_page(s.keep_mm[0], s.keep_mm[3]),
                              s.to_page(s.keep_mm[2], s.keep_mm[1]))
        h = s.size_mm[1]
        kept = doc[s.page - 1].get_textpage().get_text_bounded(
            x0 * pt, (h - y1) * pt, x1 * pt, (h - y0) * pt)
        ticks = re.findall(r"\b([xy]) (-?\d+)\b", kept)
        # both axes, read where the sheet is kept (not in a strip that is cut away)
        assert {a for a, _ in ticks} == {"x", "y"}, (s.label, kept[:200])
        for axis, value in ticks:  # and they are this sheet's coordinates
            u0, v0, u1, v1 = s.keep_mm
            lo, hi = (u0, u1) if axis == "x" else (v0, v1)
            assert lo - 1 <= int(value) <= hi + 1, (s.label, axis, value)
    doc.close()


def test_two_dozen_parts_list_on_the_first_page(tmp_path):
    parts = [_part(trimesh.creation.box([0.02, 0.01, 0.04]),
                   _pose(None, (0.05 * (i % 6), 0.05 * (i // 6), 0.02)), f"domino_run[{i}]", i + 1)
             for i in range(24)]
    r = make_template(parts, [FLOOR], tmp_path, paper="a4")
    assert r.n_pages == 1 + len(r.sheets)  # no page of its own for a few lines of the list
    text = " ".join(_text(r.pdf)[0].split())
    assert all(f"{i + 1}. domino_run[{i}] [sheet" in text for i in range(24))


def test_labels_of_a_crowded_row_do_not_cost_a_sheet(tmp_path):
    # a user's machine (five dominoes on a table push a ball off a ledge, down a ramp, into a
    # cup): the first domino's label once went 115 mm out past the table, and the template
    # took a fourth sheet for it; where the parts fit on N sheets, their labels find room too
    scenario = load_scenario("tools/generality/table_push.toml")
    _, values = resolve_layout(scenario, "hand", None)
    r = scene_template(scenario, make_scene(scenario, values, load_parts(scenario)), tmp_path,
                       paper="a4")
    x0, y0, x1, y1 = np.array([p.outline.bounds for p in r.parts]).T
    alone = grid_size(x1.max() - x0.min(), y1.max() - y0.min(), r.paper, r.orientation,
                      r.overlap_mm)
    assert r.grid == alone, (r.grid, alone)
    for p in r.parts:  # and each label still clear of every part
        label = shapely_box(*p.label_box)
        assert not any(label.intersects(q.outline) for q in r.parts), p.name


@pytest.mark.parametrize("plane, up", [("floor", "+y"), ("xz", "+z")])
def test_the_legend_names_the_axes_the_arrows_show(plane, up, tmp_path):
    # a user read "arrows 'world +x', 'world +z'" on a floor template whose arrows said +y
    scenario = load_scenario("scenarios/simple.toml")
    _, values = resolve_layout(scenario, "initial", None)
    r = scene_template(scenario, make_scene(scenario, values, load_parts(scenario)), tmp_path,
                       paper="a4", plane=plane)
    first = " ".join(_text(r.pdf)[0].split())
    assert f"world {up}" in first  # the arrow's name
    assert f"arrows 'world +x', 'world {up}': the world axes" in first
