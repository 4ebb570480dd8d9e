"""Ropes against closed forms: an Atwood machine, a taut rope that does not stretch, a slack
rope that does not pull, a rope pendulum's period, a hinged lever pulled by a hanging weight;
a rope too short for its layout is invalid; bad rope tables are refused in one line."""

import math

import numpy as np
import pytest
from _support import PARTS, run, scene_of

from rgmcad.errors import ScenarioError
from rgmcad.scene.bodies import load_parts
from rgmcad.scene.loader import parse_scenario
from rgmcad.sim.layout_validity import LayoutValidity
from rgmcad.sim.run import Outcome
from rgmcad.sim.validity import check_validity
from rgmcad.sim.world import World

G = 9.81
NEVER = {"e": {"type": "contact", "first": "a", "second": "b"}}


def ball(mass, **pose):
    return {"part": "ball", "params": {"radius": 0.02}, "mass": mass, "pose": pose}


def scenario(objects, ropes, events=NEVER, **extra):
    return parse_scenario({"name": "ropes", "objects": objects, "ropes": ropes, "events": events,
                           "simulation": {"duration": 3.0}, **extra}, where="<test>")


def rope_length(world, points, ends):
    """Path length now: ends are (body, point in its part frame); points are the fixed ones."""
    hooks = [world.pose(b)[:3, :3] @ p + world.pose(b)[:3, 3] for b, p in ends]
    path = [hooks[0], *points, hooks[1]]
    return sum(np.linalg.norm(np.subtract(q, p)) for p, q in zip(path[:-1], path[1:], strict=True))


def atwood(m1, m2, slack=0.0):
    pulleys = [[-0.1, 0, 1.0], [0.1, 0, 1.0]]
    sc = scenario({"a": ball(m1, x=-0.1, z=0.5), "b": ball(m2, x=0.1, z=0.5)},
                  {"r": {"ends": [{"object": "a"}, {"object": "b"}],
                         "pulleys": [{"point": p} for p in pulleys], "slack": slack}})
    return sc, pulleys


@pytest.mark.parametrize("m1, m2", [(0.1, 0.2), (0.05, 0.1)])
def test_atwood_machine_accelerates_at_mass_difference_over_sum_g(m1, m2):
    sc, pulleys = atwood(m1, m2)
    dt = sc.settings.timestep
    with World(scene_of(sc), sc.settings) as world:
        length0 = rope_length(world, pulleys, [("a", (0, 0, 0)), ("b", (0, 0, 0))])
        for _ in range(50):
            world.step()
        va0, vb0 = world.velocity("a")[0][2], world.velocity("b")[0][2]
        stretch = 0.0
        for _ in range(150):
            world.step()
            stretch = max(stretch, rope_length(world, pulleys, [("a", (0, 0, 0)),
                                                                ("b", (0, 0, 0))]) - length0)
        va1, vb1 = world.velocity("a")[0][2], world.velocity("b")[0][2]
    expected = (m2 - m1) / (m1 + m2) * G
    assert (va1 - va0) / (150 * dt) == pytest.approx(expected, rel=0.03)  # light side rises
    assert (vb1 - vb0) / (150 * dt) == pytest.approx(-expected, rel=0.03)
    assert stretch < 1e-3


def test_equal_masses_stay_put_and_the_rope_holds_them():
    sc, pulleys = atwood(0.1, 0.1)
    with World(scene_of(sc), sc.settings) as world:
        for _ in range(500):
            world.step()
        za, zb = world.pose("a")[2, 3], world.pose("b")[2, 3]
    assert za == pytest.approx(0.5, abs=1e-3) and zb == pytest.approx(0.5, abs=1e-3)


def hanging(slack, mass=1.0, length_key="slack"):
    """A weight hanging 0.3 m below a fixed point on a rope with ``slack`` (m)."""
    return scenario({"a": ball(mass, z=0.7), "b": ball(0.01, x=5.0)},
                    {"r": {"ends": [{"point": [0, 0, 1.0]}, {"object": "a"}],
                           length_key: slack}})


def test_slack_rope_lets_the_weight_fall_freely_then_holds_it_without_stretching():
    slack = 0.05
    sc = hanging(slack)
    dt = sc.settings.timestep
    with World(scene_of(sc), sc.settings) as world:
        zs, stretch = [], 0.0
        for _ in range(500):
            world.step()
            z = world.pose("a")[2, 3]
            zs.append(z)
            stretch = max(stretch, (1.0 - z) - (0.3 + slack))
    t = dt * np.arange(1, 501)
    free = 0.7 - 0.5 * G * t**2
    falling = free > 0.7 - slack  # before the rope can be taut
    assert falling.sum() > 40
    # free fall, to semi-implicit Euler's one-step error
    assert np.allclose(np.array(zs)[falling], free[falling], atol=G * t[falling] * dt)
    assert stretch < 1e-3  # the jerk and the 1 kg weight after it
    assert zs[-1] == pytest.approx(0.7 - slack, abs=1e-3)


def test_taut_rope_holds_a_weight_without_stretching_or_drifting():
    sc = hanging(0.0, mass=5.0)
    with World(scene_of(sc), sc.settings) as world:
        for _ in range(1500):
            world.step()
        z = world.pose("a")[2, 3]
        v = world.velocity("a")[0]
    assert abs(z - 0.7) < 1e-3
    assert np.linalg.norm(v) < 1e-3


@pytest.mark.parametrize("amplitude_deg", [5.0, 20.0])
def test_rope_pendulum_keeps_its_period(amplitude_deg):
    length = 0.5
    theta = math.radians(amplitude_deg)
    sc = scenario({"a": ball(0.05, x=length * math.sin(theta), z=1.0 - length * math.cos(theta)),
                   "b": ball(0.01, x=5.0)},
                  {"r": {"ends": [{"point": [0, 0, 1.0]}, {"object": "a"}]}})
    dt = sc.settings.timestep
    crossings = []
    with World(scene_of(sc), sc.settings) as world:
        x_prev = world.pose("a")[0, 3]
        for i in range(1, 2000):
            world.step()
            x = world.pose("a")[0, 3]
            if x_prev > 0 >= x or x_prev < 0 <= x:
                crossings.append((i - 1 + x_prev / (x_prev - x)) * dt)
            x_prev = x
    period = 2 * np.mean(np.diff(crossings))
    # finite amplitude: T = 2 pi sqrt(L / g) (1 + theta^2 / 16 + 11 theta^4 / 3072)
    exact = 2 * math.pi * math.sqrt(length / G) * (1 + theta**2 / 16 + 11 * theta**4 / 3072)
    assert len(crossings) >= 4
    assert period == pytest.approx(exact, rel=0.02)


def test_weight_on_a_rope_turns_a_hinged_lever_as_a_rigid_arm_would():
    # a lever hinged at its centre; a weight hangs 0.1 m from the axle on a taut rope
    m, d = 0.2, 0.1
    sc = scenario({"a": {"part": "lever", "mass": 0.05, "pose": {"z": 0.5},
                         "params": {"length": 0.3, "width": 0.02, "thickness": 0.01}},
                   "b": ball(m, x=d, z=0.3)},
                  {"r": {"ends": [{"object": "a", "point": [d, 0, 0]}, {"object": "b"}]}})
    lever_inertia = 0.05 * (0.3**2 + 0.01**2) / 12
    dt = sc.settings.timestep
    with World(scene_of(sc), sc.settings) as world:
        for _ in range(20):
            world.step()
        w = world.velocity("a")[1][1]
        vz = world.velocity("b")[0][2]
    alpha = m * G * d / (lever_inertia + m * d**2)  # the weight's side (+X) goes down: +Y
    assert w / (20 * dt) == pytest.approx(alpha, rel=0.03)
    assert -vz / (20 * dt) == pytest.approx(alpha * d, rel=0.03)


def test_rope_too_short_for_its_layout_is_invalid():
    sc = scenario({"a": ball(0.1, z=0.5), "b": ball(0.1, x=0.1, z=0.5)},
                  {"r": {"ends": [{"point": [0, 0, 1.0]}, {"object": "a"}], "length": 0.45}},
                  )
    validity = check_validity(scene_of(sc))
    assert not validity.valid
    assert validity.overlaps[0].depth == pytest.approx(0.05)
    assert run(sc).outcome is Outcome.INVALID
    assert not LayoutValidity(sc, load_parts(sc, PARTS))(np.zeros((1, 0)))[0]
    long_enough = scenario({"a": ball(0.1, z=0.5), "b": ball(0.1, x=0.1, z=0.5)},
                           {"r": {"ends": [{"point": [0, 0, 1.0]}, {"object": "a"}],
                                  "length": 0.5001}})
    assert check_validity(scene_of(long_enough)).valid
    assert LayoutValidity(long_enough, load_parts(long_enough, PARTS))(np.zeros((1, 0)))[0]


def test_rope_length_follows_the_layout_for_the_validity_of_many_layouts():
    sc = parse_scenario({
        "name": "ropes", "events": NEVER,
        "objects": {"a": {**ball(0.1, z=0.5), "free": {"z": [0.3, 0.7]}}, "b": ball(0.1, x=1.0)},
        "ropes": {"r": {"ends": [{"point": [0, 0, 1.0]}, {"object": "a"}], "length": 0.6}},
    }, where="<test>")
    tester = LayoutValidity(sc, load_parts(sc, PARTS))
    values = np.array([[0.3], [0.39], [0.41], [0.7]])
    expected = [check_validity(scene_of(sc, v)).valid for v in values]
    assert list(tester(values)) == expected == [False, False, True, True]


BAD = [
    ({"ends": [{"object": "a"}]}, "ropes.r.ends", "two ends"),
    ({"ends": [{"object": "nope"}, {"object": "a"}]}, "ropes.r.ends[0].object", "unknown object"),
    ({"ends": [{"point": [0, 0, 1]}, {"object": "c"}]}, "ropes.r.ends", "moving body"),
    ({"ends": [{"object": "a"}, {"object": "b"}], "pulleys": [{"object": "b"}]},
     "ropes.r.pulleys[0].object", "fixed point"),
    ({"ends": [{"object": "a"}, {"object": "b"}], "length": 1, "slack": 0.1}, "ropes.r",
     "not both"),
    ({"ends": [{"object": "a"}, {"object": "b"}], "length": -1}, "ropes.r.length", "expected"),
    ({"ends": [{"object": "a", "point": [0, 0]}, {"object": "b"}]}, "ropes.r.ends[0].point",
     "a list of 3"),
    ({"ends": [{"object": "a", "hook": 1}, {"object": "b"}]}, "ropes.r.ends[0].hook",
     "unknown key"),
    ({"ends": [{"object": "a"}, {"object": "b"}], "stretch": 1}, "ropes.r.stretch",
     "unknown key"),
]


@pytest.mark.parametrize("rope, key, words", BAD)
def test_bad_rope_tables_are_refused_in_one_line(rope, key, words):
    objects = {"a": ball(0.1), "b": ball(0.1, x=1.0),
               "c": {"part": "box", "params": {"length": 0.1, "width": 0.1, "height": 0.1},
                     "pose": {"x": 3.0}}}
    with pytest.raises(ScenarioError) as err:
        scenario(objects, {"r": rope})
    assert err.value.key == key and words in err.value.message
    assert "\n" not in str(err.value)


def test_check_and_simulate_name_a_rope_too_short(tmp_path, capsys):
    from rgmcad.cli import main

    path = tmp_path / "short.toml"
    path.write_text('name = "short"\n[objects.a]\npart = "ball"\nparams = { radius = 0.02 }\n'
                    'mass = 0.1\npose = { z = 0.5 }\n[ropes.r]\nends = [{ point = [0, 0, 1] }, '
                    '{ object = "a" }]\nlength = 0.45\n[events.e]\ntype = "falling"\nbody = "a"\n')
    assert main(["check", str(path)]) == 1  # a named layout is invalid
    out = capsys.readouterr().out
    assert "world -> a" in out and "0.45 m" in out
    assert "initial: INVALID: rope r (too short) by 50.00 mm" in out
    assert main(["simulate", str(path), "--json"]) == 1
    assert '"outcome": "invalid"' in capsys.readouterr().out


def test_simulate_pulls_with_the_ropes():
    # through simulate (the step loop of run.py), not only World.step: the light side rises
    sc = scenario({"a": ball(0.1, x=-0.1, z=0.5), "b": ball(0.2, x=0.1, z=0.5)},
                  {"r": {"ends": [{"object": "a"}, {"object": "b"}],
                         "pulleys": [{"point": [-0.1, 0, 1.0]}, {"point": [0.1, 0, 1.0]}]}},
                  events={"up": {"type": "rising", "body": "a", "min_linvel": 0.5}})
    result = run(sc)
    assert result.outcome is Outcome.SUCCESS
    # 0.5 m/s at (m2 - m1) / (m1 + m2) g, to within a step
    assert result.events[0].time == pytest.approx(0.5 / (G / 3), abs=0.005)
