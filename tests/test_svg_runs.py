"""Domino runs drawn in a vector editor: an SVG path in millimetres becomes a run that lies on
the drawn curve, with the spacing asked, and topples end to end; bad drawings are refused in
one line."""

import math

import numpy as np
import pytest
from _support import run

from rgmcad.errors import ScenarioError
from rgmcad.scene.loader import load_scenario
from rgmcad.sim.run import Outcome

DOMINO = '{ thickness = 0.007, width = 0.02, height = 0.044 }'


def drawing(d, *, size='width="300mm" height="200mm" viewBox="0 0 300 200"', group=""):
    return (f'<svg xmlns="http://www.w3.org/2000/svg" {size}><g {group}>'
            f'<path id="curve" d="{d}" fill="none" stroke="black"/></g></svg>')


def scenario(tmp_path, svg_text, path_extra="spacing = 0.02", events=None, floor=False,
             tilt=0):
    (tmp_path / "drawn.svg").write_text(svg_text)
    events = events or '[events.e]\ntype = "toppling"\nbody = "run[0]"\nangle = 45\n'
    text = f'''name = "drawn"
[simulation]
duration = 3.0
{'[objects.floor]' + chr(10) + 'part = "plane"' + chr(10) + 'friction = 0.6' if floor else ''}
[runs.run]
domino = {DOMINO}
path = {{ kind = "svg", file = "drawn.svg", {path_extra} }}
tilt = {tilt}
mass = 0.00305
friction = 0.6
free = {{ x = [-0.05, 0.05] }}
{events}'''
    (tmp_path / "drawn.toml").write_text(text)
    return load_scenario(tmp_path / "drawn.toml")


def domino_xy(sc):
    return np.array([[sc.objects[n].pose[0], sc.objects[n].pose[1], sc.objects[n].pose[3]]
                     for n in sc.runs["run"]])


def test_run_follows_a_drawn_arc_in_millimetres_with_y_up(tmp_path):
    # a quarter circle of radius 100 mm about (150, 150) in the drawing (y down), moved 10 mm
    # right by its group's transform: in metres, y up, centred on (0.16, -0.15)
    sc = scenario(tmp_path, drawing("M 50 150 A 100 100 0 0 1 150 50",
                                    group='transform="translate(10,0)"'))
    xyh = domino_xy(sc)
    radius = np.hypot(xyh[:, 0] - 0.16, xyh[:, 1] + 0.15)
    np.testing.assert_allclose(radius, 0.1, atol=5e-5)
    assert len(xyh) == math.floor(0.1 * math.pi / 2 / 0.02) + 1
    steps = np.linalg.norm(np.diff(xyh[:, :2], axis=0), axis=1)
    np.testing.assert_allclose(steps, 0.02, atol=1e-4)  # chords of 20 mm of arc
    # each domino faces along the curve: its heading is the tangent, from the circle's left
    # to its top (clockwise, with y up)
    tangent = np.degrees(np.arctan2(-(xyh[:, 0] - 0.16), xyh[:, 1] + 0.15))
    np.testing.assert_allclose((xyh[:, 2] - tangent + 180) % 360 - 180, 0, atol=0.5)


def test_count_spreads_the_dominoes_over_the_whole_path(tmp_path):
    sc = scenario(tmp_path, drawing("M 0 0 L 100 0 L 100 50"), path_extra="count = 16")
    xyh = domino_xy(sc)
    assert len(xyh) == 16
    np.testing.assert_allclose(xyh[0, :2], [0, 0], atol=1e-12)
    np.testing.assert_allclose(xyh[-1, :2], [0.1, -0.05], atol=1e-6)  # svgelements: 6 digits


def test_drawn_s_curve_of_dominoes_topples_end_to_end(tmp_path):
    curve = "M 20 100 C 80 20, 140 20, 160 100 S 240 180, 290 100"
    last = '[events.e]\ntype = "toppling"\nbody = "run[-1]"\nangle = 45\n'
    sc = scenario(tmp_path, drawing(curve), path_extra="spacing = 0.022", events=last,
                  floor=True, tilt=12)
    assert len(sc.runs["run"]) > 15
    result = run(sc)
    assert result.outcome is Outcome.SUCCESS


BAD = [
    (drawing("M 0 0 L 10 0", size='width="300" height="200"'), "spacing = 0.02",
     "physical unit"),
    (drawing("M 0 0 L 10 0 M 20 0 L 30 0"), "spacing = 0.02", "one continuous line"),
    (drawing("M 0 0 L 10 0"), 'spacing = 0.02, element = "other"', "no <path> with id"),
    ("<svg", "spacing = 0.02", "not an SVG file"),
    (drawing("M 0 0 L 10 0"), "spacing = 0.02, count = 3", "exactly one of count or spacing"),
    (drawing("M 0 0 L 10 0"), "spacing = 0.02, count_by = 1", "unknown key"),
    (drawing("M 0 0 L 10 0"), "spacing = 0.02, element = 3", "expected a string"),
    (drawing("M 0 0 A 1e9 1e9 0 0 1 1e6 0"), "spacing = 0.02", "too long to follow"),
]


@pytest.mark.parametrize("svg_text, extra, words", BAD)
def test_bad_drawings_are_refused_in_one_line(tmp_path, svg_text, extra, words):
    with pytest.raises(ScenarioError) as err:
        scenario(tmp_path, svg_text, extra)
    assert err.value.key.startswith("runs.run.path") and words in err.value.message
    assert "\n" not in str(err.value)


def test_a_missing_drawing_is_named(tmp_path):
    (tmp_path / "drawn.toml").write_text(
        f'name = "drawn"\n[runs.run]\ndomino = {DOMINO}\npath = {{ kind = "svg", '
        'file = "missing.svg", spacing = 0.02 }\n[events.e]\ntype = "toppling"\n'
        'body = "run[0]"\nangle = 45\n')
    with pytest.raises(ScenarioError, match="no SVG file .*missing.svg"):
        load_scenario(tmp_path / "drawn.toml")
