"""Validity: touching is valid, a 0.5 mm overlap is not; static pairs count; joints excluded."""

import time

import numpy as np
import pytest
from _support import scene_of, tiny

from rgmcad.sim.validity import check_validity

E = {"e": {"type": "contact", "first": "a", "second": "b"}}
CUBE = {"part": "box", "params": {"length": 0.02, "width": 0.02, "height": 0.02}}


def two_cubes(gap, static=False):
    mass = {} if static else {"mass": 0.01}
    return tiny({"a": {**CUBE, **mass, "pose": {"z": 0.5}},
                 "b": {**CUBE, **mass, "pose": {"x": 0.02 + gap, "z": 0.5}}}, E)


@pytest.mark.parametrize("static", [False, True])
def test_touching_is_valid_and_half_millimetre_overlap_is_not(static):
    assert check_validity(scene_of(two_cubes(0.0, static))).valid
    assert check_validity(scene_of(two_cubes(1e-4, static))).valid
    bad = check_validity(scene_of(two_cubes(-5e-4, static)))
    assert not bad.valid
    assert bad.overlaps[0].depth == pytest.approx(5e-4, rel=0.02)
    assert bad.overlaps[0].volume == pytest.approx(5e-4 * 0.02 * 0.02, rel=0.02)


def test_body_sunk_into_a_plane_is_invalid():
    sc = tiny({"floor": {"part": "plane"},
               "a": {"part": "ball", "params": {"radius": 0.01}, "pose": {"z": 0.0095}},
               "b": {**CUBE, "pose": {"x": 0.1, "z": 0.01}}}, E)
    result = check_validity(scene_of(sc))
    assert [(o.first, o.second) for o in result.overlaps] == [("floor", "a")]
    assert result.overlaps[0].depth == pytest.approx(5e-4, abs=5e-5)


def test_lever_and_its_own_axle_do_not_count_but_other_bodies_do():
    lever = {"part": "lever", "params": {"length": 0.2, "width": 0.02, "thickness": 0.005},
             "mass": 0.02}
    sc = tiny({"a": lever, "b": {**CUBE, "pose": {"x": 0.5}}}, E)
    assert check_validity(scene_of(sc)).valid
    # a second cube pushed through the axle (which sticks out of the plank) is caught
    sc = tiny({"a": lever, "b": {**CUBE, "pose": {"y": 0.022}}}, E)
    names = {frozenset((o.first, o.second)) for o in check_validity(scene_of(sc)).overlaps}
    assert frozenset(("a.axle", "b")) in names


def test_fifty_bodies_in_under_twenty_milliseconds():
    objects = {f"c{i}": {**CUBE, "pose": {"x": 0.03 * (i % 10), "y": 0.03 * (i // 10),
                                          "z": 0.01, "heading": 3 * i}}
               for i in range(50)}
    objects["c0"] = objects["c0"] | {"part": "box"}
    sc = tiny(objects, {"e": {"type": "contact", "first": "c0", "second": "c1"}})
    scene = scene_of(sc)
    check_validity(scene)  # build the per-part manifolds once
    start = time.perf_counter()
    for _ in range(5):
        result = check_validity(scene)
    per_call = (time.perf_counter() - start) / 5
    assert result.valid
    print(f"validity, 50 bodies: {per_call * 1e3:.1f} ms")  # a figure, not an assertion


@pytest.mark.parametrize("sink", [0.0, 5e-4, 2e-3])
def test_ball_shortcut_agrees_with_the_mesh_intersection(sink):
    from rgmcad.sim import validity
    from rgmcad.sim.cache import PartCache

    r = 0.01
    sc = tiny({"a": {"part": "ball", "params": {"radius": r}, "mass": 0.01,
                     "pose": {"z": -0.005 + r - sink, "x": 0.003}},  # on the groove's floor
               "b": {"part": "track", "params": {"length": 0.1, "width": 0.06, "height": 0.02,
                                                 "wall": 0.005}}}, E)
    scene = scene_of(sc)
    ball, track = scene.bodies["a"], scene.bodies["b"]
    analytic = validity._ball_depth(ball.built, ball.pose, track.built, track.pose)
    assert analytic == pytest.approx(sink, abs=1e-9)
    cache = PartCache()
    inter = validity._manifold(ball.built, cache).transform(ball.pose[:3, :4]) ^ (
        validity._manifold(track.built, cache).transform(track.pose[:3, :4]))
    mesh_depth = 0.0 if inter.is_empty() else validity.thickness(
        np.asarray(inter.to_mesh().vert_properties)[:, :3].astype(float))
    assert mesh_depth == pytest.approx(sink, abs=1e-4)  # the ball mesh is inscribed
    assert check_validity(scene).valid == (sink <= 2e-4)


@pytest.mark.parametrize("name", ["ballrun", "causality_switch"])
def test_many_layouts_at_once_give_the_answers_of_one_scene_at_a_time(name):
    from scipy.stats import qmc

    from rgmcad.runs.problem import ScenarioProblem
    from rgmcad.scene.bodies import make_scene
    from rgmcad.scene.design_space import bounds, world_poses, world_poses_many
    from rgmcad.sim.layout_validity import LayoutValidity

    problem = ScenarioProblem(f"scenarios/{name}.toml")
    scenario, parts = problem.scenario, problem.parts
    low, high = bounds(scenario)
    values = low + qmc.Sobol(scenario.dimension, rng=0).random(128) * (high - low)
    many = world_poses_many(scenario, values[:3])
    for row in range(3):
        for obj, pose in world_poses(scenario, values[row]).items():
            np.testing.assert_allclose(many[obj][row], pose, atol=1e-12)
    one_by_one = [check_validity(make_scene(scenario, v, parts)).valid for v in values]
    assert 0 < sum(one_by_one) < len(values)  # both answers occur
    assert LayoutValidity(scenario, parts)(values).tolist() == one_by_one


def test_a_point_deep_in_two_box_bodies_means_the_meshes_penetrate():
    """The shortcut that decides box-made pairs without manifold3d: whenever it finds a point
    at least tolerance / 2 deep in both bodies, the exact test finds a penetration; and it
    finds one for every crossing deeper than 2 mm."""
    from rgmcad.geometry import pose_matrices
    from rgmcad.sim import layout_validity, validity
    from rgmcad.sim.cache import PartCache

    sc = tiny({"a": {**CUBE, "params": {"length": 0.2, "width": 0.03, "height": 0.004}},
               "b": {"part": "track", "params": {"length": 0.1, "width": 0.06, "height": 0.02,
                                                 "wall": 0.005}}}, E)
    scene = scene_of(sc)
    a, b = scene.bodies["a"].built, scene.bodies["b"].built
    cache = PartCache()
    boxes_a, boxes_b = layout_validity._box_pieces(a, cache), layout_validity._box_pieces(b, cache)
    assert boxes_a is not None and len(boxes_b[0]) == 3  # a track is three boxes
    rng = np.random.default_rng(0)
    n = 400
    pose_a = pose_matrices(np.hstack([rng.uniform(-0.03, 0.03, (n, 3)),
                                      rng.uniform(-40, 40, (n, 3))]))
    pose_b = np.broadcast_to(np.eye(4), (n, 4, 4))
    frames_a = pose_a[:, None] @ boxes_a[0][None]  # (n, 1, 4, 4): a plank is one box
    found = np.zeros(n, dtype=bool)
    for frame_b, half_b in zip(*boxes_b, strict=True):
        found |= layout_validity._boxes_share_a_deep_point(
            frames_a[:, 0], np.broadcast_to(boxes_a[1][0], (n, 3)),
            np.broadcast_to(frame_b, (n, 4, 4)), np.broadcast_to(half_b, (n, 3)),
            validity.TOLERANCE / 2 + 1e-6)
    depth = np.array([validity._pair_penetration(a, pa, b, pb, cache)[0]
                      for pa, pb in zip(pose_a, pose_b, strict=True)])
    assert np.all(depth[found] > validity.TOLERANCE)
    deep = depth > 2e-3
    assert deep.sum() > 50 and found[deep].all()


def test_a_run_tests_each_layout_once(tmp_path, monkeypatch):
    """Layouts the run's validity test passed are simulated without a second test; a layout
    simulated without one is tested (and an invalid one is not simulated)."""
    import rgmcad.sim.run as run_module
    from rgmcad.learning import LearningSettings
    from rgmcad.runs.executor import SerialExecutor
    from rgmcad.runs.problem import ScenarioProblem
    from rgmcad.runs.store import RecordedProblem, RunStore, run_identity

    tested = []
    real = run_module.check_validity
    monkeypatch.setattr(run_module, "check_validity",
                        lambda *a, **k: tested.append(1) or real(*a, **k))
    problem = ScenarioProblem("scenarios/simple.toml")
    rng = np.random.default_rng(5)
    X = rng.random((12, problem.dimension))
    ok = problem.validity(X)
    assert 0 < ok.sum() < len(X)
    identity = run_identity("simple", "0" * 64, 0, LearningSettings())
    with RunStore(tmp_path, identity, dimension=problem.dimension,
                  events=list(problem.scenario.events)) as store:
        recorded = RecordedProblem(problem, store, SerialExecutor(problem.context))
        assert recorded.validity(X).tolist() == ok.tolist()
        records = recorded.simulate_records(X[ok])
        assert tested == [] and all(r.valid for r in records)
        untested = recorded.simulate_records(X[~ok][:1])
        assert tested == [1] and not untested[0].valid
