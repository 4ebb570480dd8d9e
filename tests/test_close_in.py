"""Knife edges in the final choice (``LearningSettings.close_in_copies``): the layout handed
out must succeed where a builder puts it almost exactly, not only on average over the large
errors rho_g weighs."""

import importlib

import numpy as np
import pytest

from rgmcad.learning import Candidate, LearningSettings, SPDModel, SuccessClassifier, verify_layout
from rgmcad.learning.close_in import close_in_sound
from rgmcad.learning.oracles import BallRegion, Label, OracleEvent, ProductOracle

# the module, not the function of the same name that rgmcad.learning exports
look_module = importlib.import_module("rgmcad.learning.second_look")

FAST = LearningSettings(svm_C_grid=(1.0, 10.0, 100.0), svm_gamma_grid=(1.0, 10.0),
                        svm_class_weights=(None,), centering_simulations=0, verify_samples=64,
                        error_radius=0.5, verify_candidates=3, active_max_iter=1)
KNIFE = np.array([0.5, 0.5])


class _Ringed:
    """Success iff (x0, x1) lies within 0.3 of the centre, except on a thin ring (radii 0.001
    to 0.002) around KNIFE: KNIFE itself succeeds, as does everything 0.01 from it, but about
    a quarter of the layouts within 1/300 of it fail (a chain balanced on a knife edge)."""

    def __init__(self):
        self.oracle = ProductOracle(2, {"hit": OracleEvent((), (0, 1),
                                                          BallRegion((0.5, 0.5), 0.3))})
        self.validity = self.oracle.validity
        self.asked = []

    def simulate(self, X):
        X = np.atleast_2d(X)
        self.asked.append(X.copy())
        ring = np.abs(np.linalg.norm(X - KNIFE, axis=1) - 0.0015) <= 0.0005
        return [Label(lab.valid, False, {e: False for e in lab.events}) if bad else lab
                for bad, lab in zip(ring, self.oracle.simulate(X), strict=True)]


def test_a_layout_on_a_knife_edge_is_found_and_a_sound_one_passes():
    oracle = _Ringed()
    assert oracle.simulate(KNIFE[None])[0].success  # it works exactly where it stands
    sound, n = close_in_sound(KNIFE, oracle.simulate, oracle.validity, 32)
    assert not sound and n == 32
    copies = oracle.asked[-1]
    assert len(copies) == 32 and np.all(np.linalg.norm(copies - KNIFE, axis=1) <= 1 / 300)
    assert np.all((copies >= 0) & (copies <= 1))
    # the same layout draws the same copies (a resumed run replays them)
    close_in_sound(KNIFE, oracle.simulate, oracle.validity, 32)
    np.testing.assert_array_equal(oracle.asked[-1], copies)
    # deep inside, and in a corner of the cube (copies outside it are not drawn)
    assert close_in_sound(np.array([0.55, 0.45]), oracle.simulate, oracle.validity, 32)[0]
    edge = ProductOracle(2, {"hit": OracleEvent((), (0, 1), BallRegion((0.0, 0.0), 0.5))})
    sound, n = close_in_sound(np.zeros(2), edge.simulate, edge.validity, 16)
    assert sound and n == 16


def _model(oracle, seed=0):
    rng = np.random.default_rng(seed)
    X = rng.random((300, 2))
    y = np.array([lab.success for lab in oracle.oracle.simulate(X)])
    clf = SuccessClassifier.from_settings(FAST, random_state=0).fit(X, y)
    return SPDModel(("hit",), {"hit": clf}, True, 1.0, False, 2)


def test_a_race_winner_on_a_knife_edge_gives_way_to_the_next_sound_candidate():
    # the optimum is the disc's centre, the most robust place under the race's errors, and
    # on a knife edge; two simulated successes a little off the centre are sound
    oracle = _Ringed()
    X = np.array([[0.64, 0.5], [0.4, 0.6]])
    labels = oracle.simulate(X)
    settings = FAST.replace(verify_samples=256)
    plain = verify_layout(_model(oracle), KNIFE, X, labels, oracle.simulate, oracle.validity,
                          settings)
    assert plain.chosen.source == "optimum"  # the race alone keeps the knife edge
    oracle.asked.clear()
    screened = verify_layout(_model(oracle), KNIFE, X, labels, oracle.simulate,
                             oracle.validity, settings.replace(close_in_copies=16))
    # the same race, then the screen: the next best-rated candidate, which is sound
    assert [c.success_rate for c in screened.candidates] == [
        c.success_rate for c in plain.candidates]
    assert screened.chosen.source.startswith("simulated sample #")
    others = [c for c in plain.candidates if c.source != "optimum"]
    assert screened.chosen.success_rate == max(c.success_rate for c in others)
    assert close_in_sound(screened.chosen.x, oracle.simulate, oracle.validity, 16)[0]
    assert screened.close_in_failed == ("optimum",) and plain.close_in_failed == ()
    assert screened.n_simulations == plain.n_simulations + 32  # two candidates screened


def test_when_no_candidate_is_sound_the_race_winner_stays():
    oracle = _Ringed()
    X = np.array([[0.95, 0.95]])  # the run's one other sample failed: no other candidate
    v = verify_layout(_model(oracle), KNIFE, X, oracle.simulate(X), oracle.simulate,
                      oracle.validity, FAST.replace(close_in_copies=16))
    assert v.chosen.source == "optimum" and v.verified and v.close_in_failed == ()


def test_a_refined_layout_on_a_knife_edge_is_not_kept(monkeypatch):
    # the second look's refined layout wins its check; on a knife edge it is not kept
    oracle = ProductOracle(2, {"hit": OracleEvent((), (0, 1), BallRegion((0.5, 0.5), 0.3))})
    rng = np.random.default_rng(0)
    X = np.column_stack([rng.uniform(0.7, 1.0, 200), rng.uniform(0.0, 1.0, 200)])
    edge = Candidate(np.array([0.76, 0.5]), "simulated sample #3", "success")
    P = edge.x + rng.normal(0, 0.1, (256, 2))
    P = P[np.all((P >= 0) & (P <= 1), axis=1)]
    seen_X, seen = np.vstack([X, P]), [*oracle.simulate(X), *oracle.simulate(P)]
    settings = FAST.replace(verify_samples=256, close_in_copies=8)
    kept = look_module.second_look(oracle, settings.replace(close_in_copies=0), seen_X, seen,
                                   edge, oracle.simulate, np.random.default_rng(0))
    assert kept.chosen is not edge  # without the screen the refined layout is kept
    screened = []
    monkeypatch.setattr(look_module, "close_in_sound",
                        lambda x, *a: screened.append(x) or (False, 8))
    look = look_module.second_look(oracle, settings, seen_X, seen, edge, oracle.simulate,
                                   np.random.default_rng(0))
    np.testing.assert_array_equal(screened[0], kept.chosen.x)
    assert look.chosen is edge and look.check is not None
    assert look.check[1].success_rate > look.check[0].success_rate
    assert look.n_simulations == kept.n_simulations + 8


@pytest.mark.parametrize("bad", [-1, 1.5])
def test_the_setting_is_a_count(bad):
    with pytest.raises(ValueError, match="close_in_copies"):
        LearningSettings(close_in_copies=bad)


def test_optimize_with_the_screen_says_what_it_did_and_otherwise_is_the_same_run(tmp_path):
    # the user's view: `optimize` on simple with and without the screen; result.json, the
    # summary's words and report.md agree; a run whose layouts all pass is the run without it
    import json

    from rgmcad.learning.settings import budget
    from rgmcad.runs.problem import ScenarioProblem
    from rgmcad.runs.workflow import optimize_scenario
    from rgmcad.shipped import scenario_path

    plain = optimize_scenario(scenario_path("simple"), seed=0, settings=budget("small"),
                              run_dir=tmp_path / "plain", workers=1).summary
    run = optimize_scenario(scenario_path("simple"), seed=0,
                            settings=budget("small").replace(close_in_copies=16),
                            run_dir=tmp_path / "screened", workers=1).summary
    assert "close_in" not in plain
    close_in = run["close_in"]
    assert close_in["copies"] == 16
    report = (tmp_path / "screened" / "report.md").read_text()
    assert ("chosen over" in run["source"]) == bool(close_in["passed_over"])
    assert ("did not, so the best-rated" in report) == bool(close_in["passed_over"])
    assert ("failed at a layout within 1/300 of itself, so the layout chosen above was kept"
            in report) == (0 in close_in["refined_not_kept"])
    problem = ScenarioProblem(scenario_path("simple"))
    sound, _ = close_in_sound(np.asarray(run["vector"]), problem.simulate, problem.validity, 16)
    if close_in["passed_over"] or close_in["refined_not_kept"]:
        assert sound or not close_in["passed_over"]
    else:  # nothing failed the screen: the same layout as without it, bit for bit
        assert run["vector"] == plain["vector"] and sound
        assert run["evaluations"] > plain["evaluations"]  # the screen's copies, journaled
    assert json.loads((tmp_path / "screened" / "layout.json").read_text())["vector"] == run["vector"]
