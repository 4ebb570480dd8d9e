"""Pictures and videos people can show: clean flat faces, a scale bar that measures what the
picture shows, labels on request, and videos slowed down with the time and events on them."""

import json
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from _support import scene_of
from PIL import Image

from rgmcad.cli import main
from rgmcad.geometry import from_pybullet
from rgmcad.scene.loader import parse_scenario
from rgmcad.sim.render import Renderer
from rgmcad.sim.world import World

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = str(ROOT / "scenarios" / "simple.toml")
# the renderer's camera looks along -(0.35, -1, 0.75) at a layout on a floor
_VIEW = np.array([0.35, -1.0, 0.75]) / np.linalg.norm([0.35, -1.0, 0.75])
RIGHT = np.cross(-_VIEW, [0.0, 0.0, 1.0])
RIGHT /= np.linalg.norm(RIGHT)


def _scenario(tmp_path, objects: str) -> str:
    path = tmp_path / "scene.toml"
    path.write_text('name = "scene"\ndescription = "a picture"\n\n[objects.floor]\n'
                    'part = "plane"\n\n' + objects + '\n[events.a_falls]\ntype = "falling"\n'
                    'body = "a"\n')
    return str(path)


def _ball(name: str, at) -> str:  # simple's ball, already in the part cache
    x, y, z = (float(v) for v in at)
    return (f'[objects.{name}]\npart = "ball"\nparams = {{ radius = 0.01 }}\nmass = 0.01\n'
            f"pose = {{ x = {x!r}, y = {y!r}, z = {z!r} }}\n\n")


def _saturated(image: np.ndarray) -> np.ndarray:
    rgb = image[:, :, :3].astype(int)
    return (rgb.max(axis=2) - rgb.min(axis=2)) > 60


def test_a_flat_face_is_drawn_in_one_shade_without_speckle_or_stripes(tmp_path):
    box = ('[objects.a]\npart = "box"\nparams = { length = 0.175, width = 0.33, '
           'height = 0.093 }\npose = { z = 0.0465 }\n\n')
    png = tmp_path / "box.png"
    assert main(["render", _scenario(tmp_path, box), "--out", str(png), "--width", "320",
                 "--height", "240", "--no-scale-bar"]) == 0
    image = np.asarray(Image.open(png).convert("RGB")).astype(float)
    # the picture's centre falls on the box's top face: one shade there
    patch = image[110:130, 150:170]
    assert patch.std(axis=(0, 1)).max() < 2.0
    # and the box is lit: its faces differ from each other and from the white background
    assert len({tuple(p) for p in image[::8, ::8].reshape(-1, 3).astype(int)}) >= 3


def test_the_scale_bar_measures_what_the_picture_shows(tmp_path):
    half = 0.05  # two balls 100 mm apart, across the view, at the layout's centre
    objects = _ball("a", -half * RIGHT + [0, 0, 0.01]) + _ball("b", half * RIGHT + [0, 0, 0.01])
    png = tmp_path / "balls.png"
    from rgmcad.scene.bodies import load_parts, make_scene
    from rgmcad.scene.layout_files import resolve_layout
    from rgmcad.scene.loader import load_scenario
    from rgmcad.sim.render import render_png

    scenario = load_scenario(_scenario(tmp_path, objects))
    _, values = resolve_layout(scenario, None, None)
    scene = make_scene(scenario, values, load_parts(scenario))
    bar_mm, bar_px = render_png(scenario, scene, png, 640, 480)
    image = np.asarray(Image.open(png).convert("RGB"))
    ys, xs = np.nonzero(_saturated(image))
    left, right = xs < 320, xs >= 320
    centres = [np.array([xs[m].mean(), ys[m].mean()]) for m in (left, right)]
    px_per_mm = np.linalg.norm(centres[1] - centres[0]) / 100.0
    assert bar_px / bar_mm == pytest.approx(px_per_mm, rel=0.03)
    # the bar drawn is that long: a dark run of pixels at the bottom left
    rows = image[int(480 * 0.8):, : 320].astype(int).sum(axis=2) < 150
    longest = max(_longest_run(r) for r in rows)
    assert longest == pytest.approx(bar_px, abs=4)


def _longest_run(row: np.ndarray) -> int:
    best = run = 0
    for v in row:
        run = run + 1 if v else 0
        best = max(best, run)
    return best


def test_labels_are_drawn_on_request_only(tmp_path):
    plain, labelled = tmp_path / "p.png", tmp_path / "l.png"
    args = ["render", SIMPLE, "--width", "320", "--height", "240"]
    assert main([*args, "--out", str(plain)]) == 0
    assert main([*args, "--out", str(labelled), "--labels"]) == 0
    a = np.asarray(Image.open(plain).convert("RGB")).astype(int)
    b = np.asarray(Image.open(labelled).convert("RGB")).astype(int)
    changed = np.abs(a - b).sum(axis=2) > 30
    assert changed.sum() > 300  # the names of ball, track and the run


def _frames(path):
    image = Image.open(path)
    out = []
    for i in range(image.n_frames):
        image.seek(i)
        out.append(np.asarray(image.convert("RGB")).astype(int))
    return out


def _seconds(mp4) -> float:
    """How long an MP4 plays, less the last 1.5 s (the last frame held to read the end)."""
    import imageio.v2 as imageio

    reader = imageio.get_reader(mp4)
    fps = reader.get_meta_data()["fps"]
    return reader.count_frames() / fps - 1.5


def test_video_is_slowed_down_and_shows_time_and_events_as_they_succeed(tmp_path, capsys):
    slow, real, gif = tmp_path / "slow.mp4", tmp_path / "real.mp4", tmp_path / "slow.gif"
    size = ["--width", "160", "--height", "120"]
    assert main(["simulate", SIMPLE, "--video", str(slow), *size, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert main(["simulate", SIMPLE, "--video", str(real), *size, "--speed", "1"]) == 0
    # a quarter of real time by default (within the first and last frames' times)
    frame = 2.5 / 30
    assert _seconds(slow) == pytest.approx(result["sim_time"] / 0.25, abs=frame)
    assert _seconds(real) == pytest.approx(result["sim_time"], abs=frame)
    assert main(["simulate", SIMPLE, "--video", str(gif), *size]) == 0
    slow_frames = _frames(gif)

    def green_dots(frame):  # the event list, left; a success's dot is filled green
        panel = frame[:100, :14]
        return ((np.abs(panel - [20, 130, 40]) < 45).all(axis=2)).sum()

    first, last = green_dots(slow_frames[0]), green_dots(slow_frames[-1])
    assert first == 0 and last > 20 * len(result["events"])
    # the time runs: the top right corner changes from frame to frame
    corner = [f[:20, -90:] for f in slow_frames[:40:10]]
    assert all(np.abs(a - b).sum() > 0 for a, b in zip(corner, corner[1:], strict=False))


GOBLET = {"inner_height": 0.11, "top_radius": 0.036, "bottom_radius": 0.025, "wall": 0.002}


def test_meshes_and_ropes_are_drawn_where_the_bodies_are():
    sc = parse_scenario({
        "name": "picture",
        "objects": {
            "cup": {"part": "goblet", "params": GOBLET, "mass": 0.01,
                    "pose": {"x": 0.1, "z": 0.3, "roll": 180}},
            "lever": {"part": "lever", "mass": 0.02, "pose": {"x": -0.2, "z": 0.1, "roll": 10},
                      "params": {"length": 0.2, "width": 0.02, "thickness": 0.01,
                                 "pivot_x": 0.05}},
        },
        "ropes": {"r": {"ends": [{"object": "cup"}, {"object": "lever", "point": [-0.1, 0, 0]}],
                        "pulleys": [{"point": [0.1, 0, 0.5]}, {"point": [-0.3, 0, 0.5]}]}},
        "events": {"e": {"type": "contact", "first": "cup", "second": "lever"}},
    }, where="<test>")
    scene = scene_of(sc)
    with World(scene, sc.settings) as world:
        for _ in range(50):
            world.step()
        renderer = Renderer(scene, 64, 64)
        try:
            renderer.image({name: world.pose(name) for name in renderer.ghosts})
            cid = renderer.engine.cid
            for name, ghost in renderer.ghosts.items():
                drawn = from_pybullet(*pb.getBasePositionAndOrientation(ghost,
                                                                        physicsClientId=cid))
                np.testing.assert_allclose(drawn, world.pose(name), atol=1e-6, err_msg=name)
            (_, beads), = renderer.ropes
            at = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0]
                           for b in beads])
            pose = world.pose("lever")
            hook = pose[:3, :3] @ [-0.1, 0, 0] + pose[:3, 3]
            np.testing.assert_allclose(at[0], world.pose("cup")[:3, 3], atol=1e-9)
            np.testing.assert_allclose(at[-1], hook, atol=1e-9)
            for pulley in ([0.1, 0, 0.5], [-0.3, 0, 0.5]):  # the beads pass over both pulleys
                assert np.linalg.norm(at - pulley, axis=1).min() < 0.003
        finally:
            renderer.close()


def test_distinct_parts_of_every_shipped_scenario_have_distinct_colours():
    # the rule (rgmcad/scene/palette.py): only the dominoes of one run share colours, two
    # shades of one, alternating; the renderer, the replay and the report read this table
    from rgmcad.scene.loader import load_scenario
    from rgmcad.scene.palette import FLOOR, STATIC, runs_of, scene_colours

    for path in sorted((ROOT / "scenarios").glob("*.toml")):
        scenario = load_scenario(path)
        scene = scene_of(scenario)
        runs = runs_of(scenario)
        colours = scene_colours(scene, runs)
        solid = [b for b in scene.bodies.values() if not b.plane]
        assert set(colours) == {b.name for b in solid}
        owner: dict[tuple, str] = {}  # colour -> the object, or the run, drawn in it
        for body in solid:
            who = runs.get(body.object, body.object)
            assert owner.setdefault(colours[body.name], who) == who, (path.name, body.name)
        assert FLOOR not in colours.values()
        for run, dominoes in scenario.runs.items():
            shades = [colours[d] for d in dominoes]
            assert len(set(shades)) == min(len(dominoes), 2), (path.name, run)
            assert all(a != b for a, b in zip(shades, shades[1:], strict=False))
        static = [colours[b.name] for b in solid if b.static and b.name == b.object]
        assert static[:len(STATIC)] == list(STATIC[:len(static)])  # muted tones, in turn


def test_the_palette_comes_round_in_new_shades_for_any_number_of_parts():
    from rgmcad.scene.palette import MOVING, object_colours

    many = object_colours([(f"o{i}", i % 3 == 0, None) for i in range(600)])
    assert len(set(many.values())) == 600  # 400 moving, 200 static: no colour twice
    assert list(many.values())[1:3] == list(MOVING[:2])
