"""A rope that passes through a body at the start makes the layout invalid, by the depth of
its deepest point inside the body; a rope beside a body, over a pulley wheel, hooked to a
surface or hanging into a goblet's cavity does not. The many-layout tester agrees."""

import numpy as np
import pytest
from _support import PARTS, run, scene_of

from rgmcad.scene.bodies import load_parts
from rgmcad.scene.loader import parse_scenario
from rgmcad.sim.layout_validity import LayoutValidity
from rgmcad.sim.run import Outcome
from rgmcad.sim.validity import check_validity

NEVER = {"e": {"type": "falling", "body": "a"}}
GOBLET = {"inner_height": 0.11, "top_radius": 0.036, "bottom_radius": 0.025, "wall": 0.002}


def ball(**pose):
    return {"part": "ball", "params": {"radius": 0.02}, "mass": 0.1, "pose": pose}


def shelf(x, **extra):
    """A static 100 x 100 x 20 mm box centred at (x, 0, 0.5)."""
    return {"part": "box", "params": {"length": 0.1, "width": 0.1, "height": 0.02},
            "pose": {"x": x, "z": 0.5}, **extra}


def hanging(objects, top=(0, 0, 1.0), pulleys=()):
    """Ball ``a`` at (0, 0, 0.2) hanging on a rope from the world point ``top``."""
    rope = {"ends": [{"point": list(top)}, {"object": "a"}], "slack": 0.01}
    if pulleys:
        rope["pulleys"] = [{"point": list(p)} for p in pulleys]
    return parse_scenario({"name": "through", "events": NEVER,
                           "objects": {"a": ball(z=0.2), **objects}, "ropes": {"r": rope}},
                          where="<test>")


def test_a_rope_through_a_box_is_invalid_by_its_depth_inside():
    # the vertical rope at x = 0 runs 5 mm inside the box's -X face, through its 20 mm height
    validity = check_validity(scene_of(hanging({"b": shelf(0.045)})))
    assert not validity.valid
    (overlap,) = validity.overlaps
    assert overlap.first == "rope r (through b)" and overlap.second == "b"
    assert overlap.depth == pytest.approx(0.005, abs=1e-5)  # reported to 10 um
    # 10 mm inside: the box's mid-height plane is the deepest (half its height)
    assert check_validity(scene_of(hanging({"b": shelf(0.0)}))).overlaps[0].depth == \
        pytest.approx(0.01, abs=1e-5)


@pytest.mark.parametrize("x, valid", [(0.0503, True), (0.0499, True), (0.0497, False),
                                      (-0.0499, True), (-0.0497, False)])
def test_a_rope_touching_a_box_is_valid_and_one_past_the_tolerance_is_not(x, valid):
    # the box's face 0.3 mm beside the rope, 0.1 mm past it (touching) or 0.3 mm past it
    assert check_validity(scene_of(hanging({"b": shelf(x)}))).valid is valid


def test_the_many_layout_tester_agrees_as_the_box_slides_across_the_rope():
    sc = parse_scenario({"name": "through", "events": NEVER,
                         "objects": {"a": ball(z=0.2), "b": {**shelf(0.0),
                                                             "free": {"x": [-0.1, 0.1]}}},
                         "ropes": {"r": {"ends": [{"point": [0, 0, 1.0]}, {"object": "a"}],
                                         "slack": 0.01}}}, where="<test>")
    values = np.linspace(-0.1, 0.1, 41)[:, None]
    expected = [check_validity(scene_of(sc, v)).valid for v in values]
    assert list(LayoutValidity(sc, load_parts(sc, PARTS))(values)) == expected
    assert expected.count(False) == 19  # |x| < 0.05 - 0.0002: x = -0.045 ... 0.045


def test_ropes_over_a_pulley_wheel_and_from_a_hook_on_a_surface_are_valid():
    # a static wheel whose rim carries the pulley point: both segments leave the rim downwards
    # through the wheel's disc (it is what the rope wraps), one to a fixed hook under a shelf
    wheel = {"part": "pulley", "params": {"radius": 0.03, "width": 0.01}, "pose": {"z": 0.8}}
    sc = hanging({"w": wheel, "b": shelf(0.2, pose={"x": 0.2, "z": 0.66})},
                 top=(0.2, 0, 0.65), pulleys=[(0, 0, 0.83)])
    assert check_validity(scene_of(sc)).valid
    # the same rope with the wheel 2 cm aside: the point is off its rim, the rope cuts through it
    moved = hanging({"w": {**wheel, "pose": {"x": 0.02, "z": 0.8}},
                     "b": shelf(0.2, pose={"x": 0.2, "z": 0.66})},
                    top=(0.2, 0, 0.65), pulleys=[(0, 0, 0.83)])
    names = {o.first for o in check_validity(scene_of(moved)).overlaps}
    assert names == {"rope r (through w)"}


def test_a_rope_into_a_goblet_is_valid_and_one_through_its_wall_is_not():
    goblet = {"part": "goblet", "params": GOBLET}
    inside = parse_scenario({"name": "g", "events": NEVER, "objects": {
        "a": ball(z=0.022), "g": goblet}, "ropes": {"r": {
            "ends": [{"point": [0, 0, 0.3]}, {"object": "a"}], "slack": 0.0}}}, where="<test>")
    assert check_validity(scene_of(inside)).valid
    slanted = parse_scenario({"name": "g", "events": NEVER, "objects": {
        "a": ball(z=0.022), "g": goblet}, "ropes": {"r": {
            "ends": [{"point": [0.2, 0, 0.1]}, {"object": "a"}], "slack": 0.0}}}, where="<test>")
    (overlap,) = check_validity(scene_of(slanted)).overlaps
    assert overlap.first == "rope r (through g)"
    assert 0.0005 < overlap.depth <= 0.001 + 1e-6  # at most half the 2 mm wall


def test_check_and_simulate_report_a_rope_moved_through_a_box(tmp_path, capsys):
    from rgmcad.cli import main

    text = ('name = "through"\n[objects.a]\npart = "ball"\nparams = { radius = 0.02 }\n'
            'mass = 0.1\npose = { z = 0.2 }\n[objects.b]\npart = "box"\n'
            'params = { length = 0.1, width = 0.1, height = 0.02 }\npose = { x = X, z = 0.5 }\n'
            '[ropes.r]\nends = [{ point = [0, 0, 1] }, { object = "a" }]\nslack = 0.01\n'
            '[events.e]\ntype = "falling"\nbody = "a"\n')
    beside, through = tmp_path / "beside.toml", tmp_path / "through.toml"
    beside.write_text(text.replace("X", "0.08"))
    through.write_text(text.replace("X", "0.03"))
    assert main(["check", str(beside)]) == 0
    assert main(["check", str(through)]) == 1
    assert "initial: INVALID: rope r (through b) by 10.00 mm" in capsys.readouterr().out
    assert main(["simulate", str(through)]) == 1
    assert "rope r (through b) by 10.00 mm" in capsys.readouterr().out
    assert run(hanging({"b": shelf(0.03)})).outcome is Outcome.INVALID


@pytest.mark.parametrize("part, params", [
    ("box", {"length": 0.1, "width": 0.06, "height": 0.02}),
    ("cylinder", {"radius": 0.03, "height": 0.05}),
])
def test_mesh_distances_match_the_solids_exact_ones(part, params):
    # the rope test's signed distance to a part's mesh against the exact one of its primitive
    # piece, at random points in and around it (a cylinder's mesh is a polygon: within its
    # tessellation's sagitta)
    from rgmcad.sim.cache import PartCache
    from rgmcad.sim.distances import signed_distances
    from rgmcad.sim.rope_validity import _signed_distance

    sc = parse_scenario({"name": "d", "events": NEVER, "objects": {
        "a": {"part": part, "params": params, "mass": 0.1}}}, where="<test>")
    built = scene_of(sc).bodies["a"].built
    (piece,) = built.pieces
    points = np.random.default_rng(3).uniform(-0.07, 0.07, (400, 3))
    local = (points - np.asarray(piece.frame)[:3, 3]) @ np.asarray(piece.frame)[:3, :3]
    exact = signed_distances(piece, local)
    ours = _signed_distance(built, PartCache())(points)
    assert np.sign(ours[np.abs(exact) > 1e-3]).tolist() == \
        np.sign(exact[np.abs(exact) > 1e-3]).tolist()
    assert np.abs(ours - exact).max() < (1e-9 if part == "box" else 5e-4)
