"""A world owns its engine: worlds alive at once do not disturb each other, an engine handed
from world to world gives what a fresh one gives, and a closed world is closed."""

import numpy as np
import pytest
from _support import PARTS, scene_of

from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.loader import load_scenario
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine
from rgmcad.sim.run import simulate
from rgmcad.sim.world import World

STEPS = 300


def _scenario(name):
    return load_scenario(f"scenarios/{name}.toml")


def _scene(name, layout="solved"):
    sc = _scenario(name)
    return scene_of(sc, values_from_mapping(sc, sc.layouts[layout])), sc.settings


def _state(world) -> np.ndarray:
    return np.stack([world.pose(n) for n in sorted(world.scene.bodies)])


def _trajectory(world, steps=STEPS) -> list[np.ndarray]:
    out = []
    for _ in range(steps):
        world.step()
        out.append(_state(world))
    return out


def test_two_live_worlds_stepped_alternately_give_their_own_trajectories():
    a_scene, a_settings = _scene("simple")
    b_scene, b_settings = _scene("ballrun")  # a goblet: compound shapes from OBJ files
    with World(a_scene, a_settings) as a:
        alone_a = _trajectory(a)
    with World(b_scene, b_settings) as b:
        alone_b = _trajectory(b)
    with World(a_scene, a_settings) as a, World(b_scene, b_settings) as b:
        assert a.cid != b.cid
        both_a, both_b = [], []
        for _ in range(STEPS):
            a.step()
            both_a.append(_state(a))
            b.step()
            both_b.append(_state(b))
    assert all(np.array_equal(x, y) for x, y in zip(alone_a, both_a, strict=True))
    assert all(np.array_equal(x, y) for x, y in zip(alone_b, both_b, strict=True))
    assert not np.array_equal(alone_b[0], alone_b[-1])  # something moved


def test_an_engine_and_a_cache_reused_from_world_to_world_change_nothing():
    sc = _scenario("ballrun")
    parts = load_parts(sc, PARTS)
    fresh = [simulate(sc, values_from_mapping(sc, sc.layouts[name]), parts)
             for name in ("solved", "initial")]
    with Engine() as engine:
        cache = PartCache()
        for _ in range(2):
            reused = [simulate(sc, values_from_mapping(sc, sc.layouts[name]), parts,
                               engine=engine, cache=cache) for name in ("solved", "initial")]
            assert [r.events for r in reused] == [r.events for r in fresh]
            assert [r.outcome for r in reused] == [r.outcome for r in fresh]
        cache.close()


def test_an_engine_holds_one_open_world_and_a_closed_world_refuses_to_step():
    scene, settings = _scene("simple", "initial")
    with Engine() as engine:
        first = World(scene, settings, engine)
        with pytest.raises(RuntimeError, match="holds a live world"):
            World(scene, settings, engine)
        first.close()
        with pytest.raises(RuntimeError, match="closed"):
            first.step()
        with World(scene, settings, engine) as second:  # the engine is free again
            second.step()
        assert engine.connected
    assert not engine.connected


def test_a_world_of_its_own_engine_disconnects_when_closed():
    sc = _scenario("simple")
    scene = make_scene(sc, values_from_mapping(sc, sc.layouts["initial"]), load_parts(sc, PARTS))
    world = World(scene, sc.settings)
    engine = world.engine
    assert engine.connected
    world.close()
    assert not engine.connected
    world.close()  # idempotent


def test_an_engine_without_its_renderer_moves_bodies_exactly_as_one_with_it():
    """The renderer only makes visual meshes: dropping it changes no bit of a trajectory."""
    scene, settings = _scene("ballrun")
    with Engine() as drawing, Engine(renderer=False) as plain:
        with World(scene, settings, drawing) as a:
            with_renderer = _trajectory(a)
        with World(scene, settings, plain) as b:
            without = _trajectory(b)
    assert all(np.array_equal(x, y) for x, y in zip(with_renderer, without, strict=True))


def _final(scenario, values, parts, **kwargs):
    poses = {}

    def observe(world, t):
        poses.update({n: world.pose(n) for n in world.handles})

    r = simulate(scenario, values, parts, observer=observe, observe_every=10**9, **kwargs)
    return r.outcome, r.events, r.steps, {n: p.tolist() for n, p in poses.items()}


def test_simulations_in_one_engine_give_fresh_results_in_any_order():
    """Worker processes simulate layouts one after another in one engine, in whatever order
    their tasks come: every result (events, times, final poses) is what a fresh process gets."""
    from rgmcad.scene.design_space import values_from_vector

    sc = _scenario("simple")
    parts = load_parts(sc, PARTS)
    rng = np.random.default_rng(4)
    layouts = [values_from_mapping(sc, sc.layouts["solved"])]
    layouts += [values_from_vector(sc, rng.random(sc.dimension)) for _ in range(3)]
    fresh = [_final(sc, v, parts) for v in layouts]
    with Engine(renderer=False) as engine:
        cache = PartCache()
        for order in ([0, 1, 2, 3], [3, 1, 0, 2, 0]):
            for k in order:
                assert _final(sc, layouts[k], parts, engine=engine, cache=cache) == fresh[k]
        cache.close()
    assert len({f[0] for f in fresh}) > 1 or len({str(f[1]) for f in fresh}) > 1


def test_hooks_run_before_every_step_and_change_nothing():
    """A per-step hook (a recorder, a constraint solved between steps) is called at every
    t = i dt before the step i, after the events; with or without hooks, the same result."""
    sc = _scenario("simple")
    parts = load_parts(sc, PARTS)
    values = values_from_mapping(sc, sc.layouts["solved"])
    seen = []
    hooked = simulate(sc, values, parts, hooks=[lambda world, t: seen.append(t)])
    plain = simulate(sc, values, parts)
    assert hooked.events == plain.events and hooked.outcome == plain.outcome
    dt = sc.settings.timestep
    assert plain.outcome.value == "success" and plain.sim_time == plain.steps * dt
    assert seen == [i * dt for i in range(plain.steps)]  # not at the step that resolved it


def test_a_hinged_body_is_where_its_pose_says_after_every_step():
    # a plank hinged near one end swings down; a ray cast at its free end meets its top face
    # where World.pose puts it (a link's pose read without forward kinematics lagged a step)
    from _support import tiny

    from rgmcad.sim.engine import pb

    lever = {"part": "lever", "mass": 0.05, "params": {
        "length": 0.2, "width": 0.02, "thickness": 0.01, "pivot_x": -0.09}}
    sc = tiny({"a": lever}, {"e": {"type": "falling", "body": "a"}})
    with World(scene_of(sc), sc.settings) as world:
        for step in range(60):
            world.step()
            if step % 20:
                continue
            pose = world.pose("a")
            tip = pose[:3, :3] @ np.array([0.08, 0.0, 0.005]) + pose[:3, 3]  # on the top face
            normal = pose[:3, 2]
            start, end = tip + 0.05 * normal, tip - 0.05 * normal
            hit = pb.rayTest(start.tolist(), end.tolist(), physicsClientId=world.cid)[0]
            assert hit[0] == world.handles["a"].uid
            assert np.linalg.norm(np.asarray(hit[3]) - tip) < 1e-6


def test_the_solver_residual_threshold_of_a_scenario_file_reaches_the_engine():
    """``[simulation] solver_residual_threshold``: a file without the key gets the default
    (1e-7, pybullet's own); a threshold every iteration meets stops the solver after its first
    iteration, and the ball and dominoes move differently."""
    import tomllib
    from pathlib import Path

    from rgmcad.scene.loader import parse_scenario

    data = tomllib.loads(Path("scenarios/simple.toml").read_text())

    def final_poses(**simulation):
        sc = parse_scenario({**data, "simulation": {**data["simulation"], **simulation}},
                            where="<test>", path=Path("scenarios/simple.toml"))
        with World(scene_of(sc, values_from_mapping(sc, sc.layouts["solved"])),
                   sc.settings) as world:
            return _trajectory(world, 400)[-1]

    plain = final_poses()
    assert np.array_equal(final_poses(solver_residual_threshold=1e-7), plain)
    assert not np.array_equal(final_poses(solver_residual_threshold=1.0), plain)
