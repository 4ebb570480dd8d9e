"""Every part placed by a hand (``--physics position=...,heading=...``): what is simulated is
the layout with each hand-placed part moved within the stated ranges in its parent's frame,
never two parts pushed into each other, joints never torn apart."""

import json
from pathlib import Path

import numpy as np
import pytest

from rgmcad.runs.problem import ScenarioContext
from rgmcad.scene.design_space import values_from_mapping, world_poses
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges, hand_placed_objects
from rgmcad.sim.run import simulate
from rgmcad.sim.validity import check_validity
from tests._support import cli_output

RAMP = str(Path(__file__).parent / "data" / "ramp.toml")
HAND = PhysicsRanges(friction=0, mass=0, restitution=0, position=0.003, heading=1.5)


class _Placed(Exception):
    """Raised by the observer at the first step: the world as the simulation built it."""


@pytest.fixture(scope="module")
def teapot():  # hinges between objects, welds, ropes over pulleys, parts resting on parts
    context = ScenarioContext.load("scenarios/teapot.toml")
    yield context
    context.close()


def _simulated_world(context, values, physics):
    """(scene, part-frame poses read back from the engine) of the world ``simulate`` built."""
    seen = {}

    def observer(world, t):
        seen["scene"] = world.scene
        seen["poses"] = {name: world.pose(name) for name in world.scene.bodies
                         if not world.scene.bodies[name].plane}
        raise _Placed

    with pytest.raises(_Placed):
        simulate(context.scenario, values, context.parts, observer=observer,
                 cache=context.cache, physics=physics)
    return seen["scene"], seen["poses"]


def _world(scenario, frames, scene, name):
    """An object's world pose in ``scene``; a frame (never placed by hand) keeps its pose
    relative to its parent (frames: the designed world poses of every object)."""
    if name in scene.bodies:
        return scene.bodies[name].pose
    parent = scenario.objects[name].parent
    if parent is None:
        return frames[name]
    return (_world(scenario, frames, scene, parent)
            @ np.linalg.inv(frames[parent]) @ frames[name])


def _local(scenario, frames, scene, name):
    """An object's pose in its parent's frame, in ``scene``."""
    parent = scenario.objects[name].parent
    pose = scene.bodies[name].pose
    if parent is None:
        return pose
    return np.linalg.inv(_world(scenario, frames, scene, parent)) @ pose


def test_each_part_lands_within_its_ranges_and_nothing_intersects(teapot):
    sc = teapot.scenario
    values = values_from_mapping(sc, sc.layouts["solved"])
    frames = world_poses(sc, values)
    designed, _ = _simulated_world(teapot, values, None)
    placed_objects = set(hand_placed_objects(
        sc, [n for n, p in teapot.parts.items() if p.infinite]))
    moved = 0
    for index in range(4):
        scene, engine_poses = _simulated_world(teapot, values, PhysicsDraw(HAND, 7, index))
        assert check_validity(scene).valid
        for name in sc.objects:
            if name not in scene.bodies or scene.bodies[name].plane:
                continue
            # the engine starts from the placed pose (no pop out of an intersection)
            np.testing.assert_allclose(engine_poses[name], scene.bodies[name].pose, atol=1e-9)
            before = _local(sc, frames, designed, name)
            after = _local(sc, frames, scene, name)
            if name not in placed_objects:  # joined to others: moves only with its parent
                np.testing.assert_allclose(after, before, atol=1e-12)
                continue
            # x and y along the parent's axes, a turn about its z; nothing else changes
            parent_shift = after[:3, 3] - before[:3, 3]
            assert np.all(np.abs(parent_shift[:2]) <= HAND.position + 1e-12), name
            assert abs(parent_shift[2]) < 1e-12, name
            turn = after[:3, :3] @ before[:3, :3].T
            np.testing.assert_allclose(turn[2], [0, 0, 1], atol=1e-12)
            assert abs(np.degrees(np.arctan2(turn[1, 0], turn[0, 0]))) <= HAND.heading + 1e-9
            moved += np.linalg.norm(parent_shift) > 1e-4
        for joint in sc.joints:  # hinges and welds between objects: never torn apart
            for a, b in zip(joint.objects, joint.objects[1:], strict=False):
                np.testing.assert_allclose(
                    np.linalg.inv(scene.bodies[a].pose) @ scene.bodies[b].pose,
                    np.linalg.inv(designed.bodies[a].pose) @ designed.bodies[b].pose,
                    atol=1e-12)
    assert moved >= 4 * len(placed_objects) // 2  # most parts really moved, in every draw


def test_the_same_draw_places_every_part_the_same_way_another_draw_does_not(teapot):
    sc = teapot.scenario
    values = values_from_mapping(sc, sc.layouts["solved"])
    first, _ = _simulated_world(teapot, values, PhysicsDraw(HAND, 3, 0))
    again, _ = _simulated_world(teapot, values, PhysicsDraw(HAND, 3, 0))
    other, _ = _simulated_world(teapot, values, PhysicsDraw(HAND, 3, 1))
    for name, body in first.bodies.items():
        np.testing.assert_array_equal(body.pose, again.bodies[name].pose)
    assert any(not np.array_equal(body.pose, other.bodies[name].pose)
               for name, body in first.bodies.items())


def test_parts_pushed_into_each_other_are_drawn_again_until_none_are(teapot):
    # 3 cm and 10 degrees: most first draws push a part into a neighbour
    wide = PhysicsRanges(friction=0, mass=0, restitution=0, position=0.03, heading=10)
    sc = teapot.scenario
    values = values_from_mapping(sc, sc.layouts["solved"])
    for index in range(3):
        scene, _ = _simulated_world(teapot, values, PhysicsDraw(wide, 0, index))
        assert check_validity(scene).valid



def test_evaluate_with_every_part_placed_by_hand(tmp_path):
    argv = ["evaluate", RAMP, "--layout", "central", "--rho-g", "--samples", "1", "--workers", "1",
            "--out", str(tmp_path / "r.png")]
    code, out, _ = cli_output([*argv, "--json", "--physics", "position=0.002,heading=1"])
    assert code == 0
    ranges = json.loads(out)["physics"]["ranges"]
    assert ranges["position"] == 0.002 and ranges["heading"] == 1 and ranges["friction"] == 0.2
    code, out, _ = cli_output([*argv, "--physics", "position=0.002,heading=1"])
    assert code == 0 and "every part within +-2 mm and +-1 deg" in out
    code, out, _ = cli_output([*argv, "--json"])  # the default: no hand's errors, none in the JSON
    assert "position" not in json.loads(out)["physics"]["ranges"]


@pytest.mark.parametrize("ranges", ["position=0.5", "heading=-1", "heading=45", "position=x"])
def test_bad_hand_ranges_are_one_line_and_status_2(ranges):
    code, out, err = cli_output(["evaluate", RAMP, "--layout", "central", "--physics", ranges])
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and "--physics" in err
    assert ranges.split("=")[0] in err and "Traceback" not in err


def _replay_start(page: Path) -> dict:
    """{body: position} of the first frame of a replay page written by ``simulate --html``."""
    text = page.read_text()
    start = text.index('id="rgmcad-replay-data">') + len('id="rgmcad-replay-data">')
    payload = json.loads(text[start:text.index("</script>", start)])
    return {b["name"]: np.asarray(b["position"]) for b in payload["bodies"]}


def test_simulate_replays_one_hand_placed_build(teapot, tmp_path):
    ranges = "friction=0,mass=0,restitution=0,position=0.003,heading=1.5"
    page = tmp_path / "built.html"
    argv = ["simulate", "scenarios/teapot.toml", "--layout", "solved", "--json"]
    code, out, err = cli_output([*argv, "--physics", ranges, "--draw", "2", "--seed", "5",
                           "--html", str(page)])
    assert code in (0, 1) and not err, err
    built = json.loads(out)
    assert built["physics"] == {"ranges": HAND.to_json(), "seed": 5, "draw": 2}
    # the replay starts where that draw's hand put every part, the simulation's own world
    sc = teapot.scenario
    values = values_from_mapping(sc, sc.layouts["solved"])
    _, placed = _simulated_world(teapot, values, PhysicsDraw(HAND, 5, 2))
    _, designed = _simulated_world(teapot, values, None)
    shown = _replay_start(page)
    assert shown.keys() == placed.keys()
    for name, position in shown.items():
        np.testing.assert_allclose(position, placed[name][:3, 3], atol=1e-9)
    assert sum(np.linalg.norm(shown[n] - designed[n][:3, 3]) > 5e-4 for n in shown) >= 5
    # the same draw is the same build; the summary names it in words
    code, out, _ = cli_output([*argv, "--physics", ranges, "--draw", "2", "--seed", "5"])
    assert json.loads(out)["events"] == built["events"]
    code, out, _ = cli_output(argv[:-1] + ["--physics", ranges, "--draw", "2", "--seed", "5"])
    assert "draw 2 (seed 5)" in out and "every part within +-3 mm and +-1.5 deg" in out


@pytest.mark.parametrize("argv", [["--draw", "1"], ["--seed", "3"],
                                  ["--physics", "position=0.002", "--draw", "-1"],
                                  ["--physics", "heading=99"]])
def test_bad_simulate_draws_are_one_line_and_status_2(argv):
    code, out, err = cli_output(["simulate", RAMP, "--layout", "central", *argv])
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert any(flag in err for flag in ("--draw", "--seed", "--physics"))


def test_a_video_shows_the_same_build_as_the_timeline(tmp_path):
    argv = ["simulate", "scenarios/simple.toml", "--json"]
    hand = ["--physics", "position=0.003,heading=1.5", "--draw", "3"]
    times = {}
    for key, extra in (("designed", []), ("built", hand),
                       ("video", [*hand, "--video", str(tmp_path / "v.gif"), "--width", "32",
                                  "--height", "24"])):
        code, out, _ = cli_output([*argv, *extra])
        times[key] = [e["time"] for e in json.loads(out)["events"]]
    assert times["video"] == times["built"] != times["designed"]
    assert (tmp_path / "v.gif").stat().st_size > 0
