"""Ropes on printed templates: the printed sheets, cut and laid by their marks, show each
rope's path where the scene has it (hooks and pulley points), and the label and the parts
list give the length to cut."""

from __future__ import annotations

import numpy as np
import pypdfium2 as pdfium
import pytest
from _support import scene_of
from test_template import CANVAS_PX_PER_MM, render, stitch

from rgmcad.printing.ropes import ROPE_RGB
from rgmcad.printing.template import scene_template
from rgmcad.scene.loader import parse_scenario


def ball(**pose):
    return {"part": "ball", "params": {"radius": 0.02}, "mass": 0.1, "pose": pose}


@pytest.fixture(scope="module")
def printed(tmp_path_factory):
    # an Atwood machine in the XZ plane over two pulley points, one rope with 20 mm slack,
    # and a second rope from a hook on a shelf, which is longer than its path
    sc = parse_scenario({
        "name": "atwood", "events": {"e": {"type": "falling", "body": "a"}},
        "objects": {"a": ball(x=-0.1, z=0.1), "b": ball(x=0.15, z=0.05),
                    "shelf": {"part": "box", "params": {"length": 0.1, "width": 0.04,
                                                        "height": 0.01},
                              "pose": {"x": 0.3, "z": 0.3}}},
        "ropes": {"lift": {"ends": [{"object": "a"}, {"object": "b"}],
                           "pulleys": [{"point": [-0.1, 0, 0.35]}, {"point": [0.15, 0, 0.35]}],
                           "slack": 0.02},
                  "tie": {"ends": [{"object": "shelf", "point": [0.02, 0, -0.005]},
                                   {"object": "b", "point": [0.02, 0, 0]}], "length": 0.4}},
    }, where="<test>")
    scene = scene_of(sc)
    result = scene_template(sc, scene, tmp_path_factory.mktemp("ropes"), plane="xz", paper="a4")
    return sc, scene, result, render(result.pdf)


def test_each_rope_is_printed_along_its_path(printed):
    _, scene, result, pages = printed
    canvas = stitch(result, pages)
    target = np.array([round(255 * c) for c in ROPE_RGB], np.int16)
    mask = np.abs(canvas.astype(np.int16) - target).max(axis=2) <= 40
    ys, xs = np.nonzero(mask)
    u0, _, _, v1 = result.extent_mm
    inked = np.stack([u0 + (xs + 0.5) / CANVAS_PX_PER_MM, v1 - (ys + 0.5) / CANVAS_PX_PER_MM], 1)
    paths = {r.name: result.frame.to_drawing(r.points) for r in scene.ropes}
    assert set(paths) == {r.name for r in result.ropes}
    for rope in scene.ropes:  # the scene's path, every 2 mm, is inked within 0.5 mm
        path = paths[rope.name]
        assert np.allclose(next(r for r in result.ropes if r.name == rope.name).path_mm, path)
        for a, b in zip(path[:-1], path[1:], strict=True):
            n = max(2, int(np.linalg.norm(b - a) / 2.0))
            for p in a + np.linspace(0, 1, n)[:, None] * (b - a):
                assert np.linalg.norm(inked - p, axis=1).min() < 0.5
        # the XZ plane holds the rope: the printed path is as long as the rope's
        drawn = np.linalg.norm(np.diff(path, axis=0), axis=1).sum()
        assert drawn == pytest.approx(rope.initial_length * 1000, abs=1e-6)
    # and nothing else is inked in rope colour: each inked point lies on a path or on the
    # circle (1.2 mm) round one of its points
    def distance_to(path, pts):
        best = np.full(len(pts), np.inf)
        for a, b in zip(path[:-1], path[1:], strict=True):
            t = np.clip((pts - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
            best = np.minimum(best, np.linalg.norm(pts - a - t[:, None] * (b - a), axis=1))
        return best

    near = np.min([distance_to(p, inked) for p in paths.values()], axis=0)
    corners = np.concatenate(list(paths.values()))
    on_circle = np.min(np.linalg.norm(inked[:, None] - corners[None], axis=2), axis=1) < 1.8
    assert np.all((near < 0.6) | on_circle)


def test_label_and_parts_list_give_the_length_to_cut(printed):
    _, scene, result, _ = printed
    doc = pdfium.PdfDocument(str(result.pdf))
    text = " ".join(doc[i].get_textpage().get_text_range() for i in range(len(doc)))
    doc.close()
    text = " ".join(text.split())
    lift = next(r for r in scene.ropes if r.name == "lift")
    assert lift.length == pytest.approx(lift.initial_length + 0.02)
    cut = f"cut {lift.length * 1000:.0f} mm (+ knots); path {lift.initial_length * 1000:.0f} mm"
    assert text.count(cut) == 2  # its label, and the parts list
    assert "a -> 2 pulleys -> b" in text
    assert text.count("cut 400 mm (+ knots)") == 2 and "shelf -> b" in text
    assert "rope lift [sheet" in text and "rope tie [sheet" in text
    svg = result.svg.read_text()
    assert 'id="rope-lift"' in svg and 'id="rope-tie"' in svg


def test_template_json_gives_each_ropes_length_and_path(tmp_path, capsys):
    import json

    from rgmcad.cli import main
    from rgmcad.scene.design_space import values_from_mapping
    from rgmcad.scene.loader import load_scenario

    assert main(["template", "teapot", "--layout", "solved", "--out", str(tmp_path),
                 "--json"]) == 0
    (rope,) = json.loads(capsys.readouterr().out)["ropes"]
    sc = load_scenario("scenarios/teapot.toml")
    (expected,) = scene_of(sc, values_from_mapping(sc, sc.layouts["solved"])).ropes
    assert rope["name"] == "gate_pulley" and rope["length"] == pytest.approx(0.5)
    assert rope["path_length"] == pytest.approx(expected.initial_length)
    assert np.allclose(rope["path_world"], expected.points)
