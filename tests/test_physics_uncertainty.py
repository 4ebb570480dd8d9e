"""Robustness to physics, not only to placement: a block that must slide off a tilted board
(it slides only while tan(slope) exceeds the friction between block and board)."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rgmcad.errors import UsageError
from rgmcad.runs.problem import ScenarioContext, SimRecord, worst_of
from rgmcad.runs.robustness import local_robustness
from rgmcad.scene.bodies import make_scene
from rgmcad.scene.design_space import values_from_mapping, vector_from_values
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsDraw, PhysicsRanges, corner_worlds
from rgmcad.sim.run import Outcome
from rgmcad.sim.world import World
from tests._support import cli_output

RAMP = str(Path(__file__).parent / "data" / "ramp.toml")
# friction 1.0 x 0.5 = 0.5: the block slides above atan(0.5) = 26.6 degrees. At 30 degrees it
# needs the friction less than 0.577 (+15 %), at 45 degrees less than 1 (+100 %).


@pytest.fixture(scope="module")
def ramp():
    context = ScenarioContext.load(RAMP)
    yield context
    context.close()


def _x(context, name):
    sc = context.scenario
    return vector_from_values(sc, values_from_mapping(sc, sc.layouts[name]))


def _rho_at_zero(context, name, physics, n=16, seed=0):
    def simulate(X, draws=None):
        draws = [None] * len(X) if draws is None else draws
        return [context.simulate_one(x, physics=d) for x, d in zip(X, draws, strict=True)]

    return local_robustness(_x(context, name), context.validity, simulate, n, seed,
                            eps=np.array([0.0]), physics=physics)


def test_a_block_at_the_friction_edge_fails_on_a_real_table_a_steep_one_does_not(ramp):
    edge = _rho_at_zero(ramp, "edge", DEFAULT_PHYSICS)
    central = _rho_at_zero(ramp, "central", DEFAULT_PHYSICS)
    assert edge.rho[0] == 1.0  # placement errors alone never stop it
    assert edge.physics.rho[0] < 1.0  # +-20 % friction sometimes does
    assert central.rho[0] == central.physics.rho[0] == 1.0
    assert edge.physics.simulations == edge.simulations == 16


def test_zero_width_ranges_give_exactly_todays_outcomes(ramp):
    x = _x(ramp, "edge")
    zero = PhysicsRanges(friction=0, mass=0, restitution=0)
    a, b = ramp.simulate_one(x, physics=PhysicsDraw(zero, 3, 5)), ramp.simulate_one(x)
    assert (a.outcome, a.events) == (b.outcome, b.events)
    curve = _rho_at_zero(ramp, "edge", zero, n=4)
    assert np.array_equal(curve.physics.successes, curve.successes)


_OUTCOMES = """
import json, sys
from rgmcad.runs.problem import ScenarioContext
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsDraw
context = ScenarioContext.load(sys.argv[1])
x = [float(v) for v in sys.argv[2].split(",")]
print(json.dumps([context.simulate_one(x, physics=PhysicsDraw(DEFAULT_PHYSICS, 11, i)).to_json()
                  ["events"] for i in range(6)]))
"""


def test_physical_draws_are_the_same_in_another_process(ramp):
    x = _x(ramp, "edge")
    here = [ramp.simulate_one(x, physics=PhysicsDraw(DEFAULT_PHYSICS, 11, i)).to_json()["events"]
            for i in range(6)]
    there = subprocess.run([sys.executable, "-c", _OUTCOMES, RAMP, ",".join(repr(float(v)) for v in x)],
                           capture_output=True, text=True, check=True).stdout
    assert json.loads(there) == here
    assert len({json.dumps(e) for e in here}) > 1  # the draws do differ from each other


def test_a_draw_gives_a_body_the_same_factors_in_every_layout(ramp):
    sc = ramp.scenario
    scenes = [make_scene(sc, values_from_mapping(sc, sc.layouts[n]), ramp.parts)
              for n in ("edge", "central")]
    draw = PhysicsDraw(DEFAULT_PHYSICS, 0, 4)
    a, b = (draw.apply(s).bodies["block"].physical for s in scenes)
    assert a == b != scenes[0].bodies["block"].physical
    other = PhysicsDraw(DEFAULT_PHYSICS, 0, 5).apply(scenes[0]).bodies["block"].physical
    assert other != a


def test_a_heavier_block_has_the_inertia_of_a_heavier_block(ramp):
    sc = ramp.scenario
    scene = make_scene(sc, values_from_mapping(sc, sc.layouts["edge"]), ramp.parts)
    ranges = PhysicsRanges(friction=0.2, mass=0.1, restitution=0)
    draw = next(d for d in (PhysicsDraw(ranges, 0, i) for i in range(50))
                if abs(d.factors("block")[1] - 1) > 0.03)
    friction, mass, _ = draw.factors("block")

    def dynamics(s):
        with World(s, sc.settings) as world:
            h = world.handles["block"]
            info = world.engine.getDynamicsInfo(h.uid, h.link)
        return info[0], np.array(info[2]), info[1]  # mass, inertia diagonal, friction

    m0, i0, f0 = dynamics(scene)
    m1, i1, f1 = dynamics(draw.apply(scene))
    assert m1 / m0 == pytest.approx(mass, rel=1e-6)
    assert i1 / i0 == pytest.approx(np.full(3, mass), rel=1e-6)
    assert f1 / f0 == pytest.approx(friction, rel=1e-6)



def test_evaluate_reports_both_robustness_figures(tmp_path):
    code, out, _ = cli_output(["evaluate", RAMP, "--layout", "central", "--rho-g", "--samples", "1",
                              "--workers", "1", "--out", str(tmp_path / "r.png"), "--json",
                              "--physics", "friction=0.3,mass=0.05"])
    result = json.loads(out)
    assert code == 0 and (tmp_path / "r.png").stat().st_size > 0
    phys = result["physics"]
    assert phys["ranges"] == {"friction": 0.3, "mass": 0.05, "restitution": 0.2}
    assert phys["simulations"] == result["simulations"] == sum(result["counts"])
    low, high = phys["rho_g_interval"]
    assert low <= phys["rho_g"] <= high and len(phys["curve"]) == len(result["curve"])
    code, out, _ = cli_output(["evaluate", RAMP, "--layout", "central", "--rho-g", "--samples", "1",
                              "--workers", "1", "--out", str(tmp_path / "r.png"), "--json",
                              "--physics", "off"])
    assert json.loads(out)["physics"] is None
    assert json.loads(out)["curve"] == result["curve"]  # the same placement errors
    # read as text, the count covers every simulation that ran, both kinds of error
    code, out, _ = cli_output(["evaluate", RAMP, "--layout", "central", "--rho-g", "--samples", "1",
                              "--workers", "1", "--out", str(tmp_path / "r.png"),
                              "--physics", "friction=0.3,mass=0.05"])
    n = result["simulations"]
    assert code == 0 and f"from {n} simulations (and {n} with physical errors" in out


@pytest.mark.parametrize("ranges", ["friction=2", "mass=-0.1", "mass=abc", "gravity=0.1",
                                    "friction", ""])
def test_bad_physics_ranges_are_one_line_and_status_2(ranges):
    code, out, err = cli_output(["evaluate", RAMP, "--layout", "edge", "--physics", ranges])
    assert code == 2 and not out
    assert len(err.strip().splitlines()) == 1 and "--physics" in err and "Traceback" not in err


def test_bad_ranges_in_settings_name_the_key():
    with pytest.raises(UsageError, match="friction"):
        PhysicsRanges(friction=1.5)
    with pytest.raises(UsageError, match="restitution"):
        PhysicsRanges(restitution=float("nan"))


def test_optimize_reports_both_robustness_figures(tmp_path):
    code, out, _ = cli_output(["optimize", RAMP, "--budget", "small", "--robustness", "1",
                              "--workers", "1", "--run", str(tmp_path / "run"), "--json"])
    robustness = json.loads(out)["robustness"]
    assert code == 0 and robustness["samples_per_radius"] == 1
    for figure in (robustness, robustness["physics"]):
        low, high = figure["rho_g_interval"]
        assert 0 <= low <= figure["rho_g"] <= high <= 1
    report = (tmp_path / "run" / "report.md").read_text()
    assert "placement errors" in report and "placement plus physical errors" in report
    # the summary a person reads counts the estimate's simulations apart from the run's
    code, out, _ = cli_output(["optimize", RAMP, "--budget", "small", "--robustness", "1",
                              "--workers", "1", "--run", str(tmp_path / "run")])
    estimate = robustness["simulations"] + robustness["physics"]["simulations"]
    assert code == 0 and estimate == 2 * 30
    assert f"replayed) and {estimate} for the rho_g estimate and " in out


@pytest.mark.parametrize("argv, flag", [
    (["--robustness", "-1"], "--robustness"), (["--physics", "mass=1"], "--physics")])
def test_optimize_refuses_bad_robustness_flags_before_simulating(tmp_path, argv, flag):
    code, out, err = cli_output(["optimize", RAMP, "--budget", "small", "--run",
                                str(tmp_path / "run"), *argv])
    assert code == 2 and not out and len(err.strip().splitlines()) == 1 and flag in err
    assert not (tmp_path / "run" / "simulations.jsonl").exists()


def test_learning_with_physical_noise_labels_edge_layouts_as_a_real_table_would(tmp_path, ramp):
    run = tmp_path / "noisy"
    argv = ["optimize", RAMP, "--budget", "small", "--robustness", "0", "--workers", "1",
            "--run", str(run)]
    code, out, _ = cli_output([*argv, "--physics-noise", "--physics", "friction=0.3"])
    assert code in (0, 1) and "physics_noise" in json.loads((run / "settings.json").read_text())
    rows = [json.loads(line) for line in (run / "simulations.jsonl").read_text().splitlines()]
    flipped = [r for r in rows if ramp.simulate_one(r["vector"]).outcome.value != r["outcome"]]
    assert flipped and len(flipped) < len(rows) / 2  # noisy near the edge, not everywhere
    code, _, err = cli_output(argv)  # the same directory without noise: another run
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_learning_at_the_corners_labels_a_layout_by_the_grippiest_table(tmp_path):
    # +-20 % friction on both bodies: the contact's friction runs from 0.32 to 0.72, so the
    # block slides at both ends only above atan(0.72) = 35.8 degrees (26.6 as designed).
    run = tmp_path / "corners"
    argv = ["optimize", RAMP, "--budget", "small", "--robustness", "0", "--workers", "1",
            "--run", str(run)]
    code, out, _ = cli_output([*argv, "--physics-corners", "--json"])
    assert code == 0 and "physics_corners" in json.loads((run / "settings.json").read_text())
    rows = [json.loads(line) for line in (run / "simulations.jsonl").read_text().splitlines()]
    slope = {abs(-50 + 30 * r["vector"][0]): r["outcome"] for r in rows if r["valid"]}
    assert all(v == "success" for s, v in slope.items() if s > 37.0)
    assert all(v == "failure" for s, v in slope.items() if s < 34.5)
    assert any(26.6 < s < 34.5 for s in slope)  # where the designed table would succeed
    assert abs(json.loads(out)["values"]["board.roll"]) > 35.8
    code, out, _ = cli_output([*argv, "--physics-corners"])  # finished: read back, as read
    n = len(rows)
    assert code == 0 and f"{n} layouts simulated in 2 physical worlds each, {2 * n} simulations" in out
    assert "2 physical worlds" in (run / "report.md").read_text()
    code, _, err = cli_output(argv)  # the same directory with plain labels: another run
    assert code == 2 and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize("extra", [["--physics", "off"], ["--physics-noise"],
                                   ["--physics", "friction=0,mass=0,restitution=0,position=0.002"]])
def test_corners_without_physical_ranges_are_refused_in_one_line(tmp_path, extra):
    code, out, err = cli_output(["optimize", RAMP, "--budget", "small", "--run",
                                str(tmp_path / "run"), "--physics-corners", *extra])
    assert code == 2 and not out and len(err.strip().splitlines()) == 1
    assert "--physics-corners" in err and not (tmp_path / "run").exists()


def test_a_corner_moves_every_body_to_the_same_end_of_every_range(ramp):
    sc = ramp.scenario
    scene = make_scene(sc, values_from_mapping(sc, sc.layouts["edge"]), ramp.parts)
    ranges = PhysicsRanges(friction=0.2, mass=0.1, restitution=0.3, position=0.01)
    low, high = corner_worlds(ranges)
    for corner, sign in ((low, -1), (high, 1)):
        assert not corner.ranges.moves_parts  # parts stay where designed
        for name, body in corner.apply(scene).bodies.items():
            before = scene.bodies[name].physical
            assert body.physical.friction == pytest.approx(before.friction * (1 + sign * 0.2))
            assert body.physical.restitution == pytest.approx(
                min(before.restitution * (1 + sign * 0.3), 1.0))
            for key in ("mass", "density"):
                if getattr(before, key) is not None:
                    assert getattr(body.physical, key) == pytest.approx(
                        getattr(before, key) * (1 + sign * 0.1))


def test_the_worst_of_several_worlds_fails_where_any_of_them_fails():
    def record(outcome, **events):
        return SimRecord(True, Outcome(outcome), events, 1.0)

    a = record("success", start=(True, 0.1), hit=(True, 0.5), stop=(True, 0.9))
    b = record("failure", start=(True, 0.2), hit=(False, 0.4), stop=(None, None))
    c = record("failure", start=(True, 0.1), hit=(None, None), stop=(None, None))
    assert worst_of([a, a]) == SimRecord(True, Outcome.SUCCESS, a.events, 2.0)
    both = worst_of([a, b])
    assert both.outcome is Outcome.FAILURE and both.seconds == 2.0
    assert both.events == {"start": (True, 0.2), "hit": (False, 0.4), "stop": (None, None)}
    assert worst_of([a, c]).events["hit"] == (None, None)
    invalid = SimRecord(False, Outcome.INVALID, {}, 0.5)
    assert worst_of([invalid]).outcome is Outcome.INVALID
