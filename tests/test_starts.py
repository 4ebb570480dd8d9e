"""`rgmcad optimize --start LAYOUT`: the user's own layout as a start. On synthetic oracles,
a start inside a success region the paper's exploration cannot find leads the result there,
the returned layout is never less robust than the start, and without starts nothing changes;
on the real simulator, the command end to end and its refusals."""

import hashlib
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from rgmcad.cli import main
from rgmcad.errors import RgmcadError
from rgmcad.learning import (
    BallRegion,
    LearningSettings,
    OracleEvent,
    ProductOracle,
    explore,
    learn_and_optimize,
    verify_layout,
)
from tests._support import TINY, run_cli

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_learning import _Pinhole, chain_oracle, disc_model  # noqa: E402

SMALL = LearningSettings(
    n_initial=64, n_successes=16, exploration_batch=8, exploration_max_iter=12,
    active_batch=8, active_max_iter=1, svm_C_grid=(1.0, 10.0, 100.0),
    svm_gamma_grid=(1.0, 10.0), svm_class_weights=(None,), mi_null_permutations=2,
    placement_samples=32, optimizer_max_eval=100, error_radius=0.0, verify_samples=32,
    centering_simulations=0,
)

# 8-D: a ball of radius 0.2 holds about 1e-5 of the cube, far from the centre.
HIDDEN_CENTRE = (0.15, 0.85, 0.2, 0.8, 0.15, 0.85, 0.2, 0.8)


def hidden_oracle():
    """Success only in a small ball of the 8-D design space."""
    return ProductOracle(8, {"land": OracleEvent((), tuple(range(8)),
                                                 BallRegion(HIDDEN_CENTRE, 0.2))})


def _choose(oracle, result, settings, starts=None):
    return verify_layout(result.model, result.x, result.X, result.labels, oracle.simulate,
                         oracle.validity, settings, starts=starts)


@pytest.mark.parametrize("seed", [0, 1])
def test_a_start_in_a_hidden_region_leads_the_result_there(seed):
    oracle = hidden_oracle()
    region = oracle.events["land"].region
    hand = np.asarray(HIDDEN_CENTRE) + np.r_[0.12, np.zeros(7)]  # works, near the edge
    assert oracle.simulate(hand[None])[0].success

    blind = learn_and_optimize(oracle, SMALL, seed)
    assert not region.contains(blind.X).any()  # the paper's exploration never gets there
    assert not _choose(oracle, blind, SMALL).verified

    result = learn_and_optimize(oracle, SMALL, seed, starts=hand[None])
    np.testing.assert_array_equal(result.X[0], hand)  # simulated first
    assert region.contains(result.X).sum() >= 4  # the exploration grew around the start
    chosen = _choose(oracle, result, SMALL, {"hand": hand})
    assert chosen.verified and region.contains(chosen.chosen.x[None])[0]
    start = next(c for c in chosen.candidates if c.source == "start layout 'hand'")
    assert chosen.chosen.success_rate >= start.success_rate


def test_the_layout_returned_is_never_less_robust_than_the_start():
    """The start is the centre of the only wide region; every other success is in a thin
    slab that the model may well prefer. The verification keeps the start (or a layout that
    does as well under the same errors)."""
    oracle = ProductOracle(3, {"hit": OracleEvent((), (0, 1, 2), BallRegion((0.5,) * 3, 0.12))})
    hand = np.full(3, 0.5)
    settings = SMALL.replace(n_initial=32, n_successes=8, verify_noise=0.08)
    result = learn_and_optimize(oracle, settings, 0, starts=hand[None])
    chosen = _choose(oracle, result, settings, {"hand": hand})
    rates = {c.source: c.success_rate for c in chosen.candidates}
    assert "start layout 'hand'" in rates
    assert chosen.chosen.success_rate >= rates["start layout 'hand'"]
    assert chosen.chosen.success_rate == max(rates.values())


def test_a_start_beats_fragile_candidates_and_ties_go_to_the_optimum():
    """verify_layout alone: an optimum on the edge of a disc, a start at its centre."""
    oracle = ProductOracle(2, {"hit": OracleEvent((), (0, 1), BallRegion((0.5, 0.5), 0.3))})
    X = np.array([[0.5, 0.78], [0.22, 0.5], [0.5, 0.5]])  # the last one is the start
    labels = oracle.simulate(X)
    settings = SMALL.replace(verify_samples=64, verify_noise=0.05, verify_candidates=2)
    model = learn_and_optimize(oracle, settings, 0).model  # any model: it only ranks

    def check(x_opt, starts):
        return verify_layout(model, np.asarray(x_opt), X, labels, oracle.simulate,
                             oracle.validity, settings, starts=starts)

    edge = check([0.79, 0.5], {"hand": X[2]})
    assert [c.source for c in edge.candidates][:2] == ["optimum", "start layout 'hand'"]
    assert edge.chosen.source == "start layout 'hand'" and edge.chosen.success_rate == 1.0
    assert check([0.79, 0.5], None).chosen.source != "start layout 'hand'"
    # the optimum at the start itself: one candidate, not two
    same = check([0.5, 0.5], {"hand": X[2]})
    assert same.chosen.source == "optimum"
    assert all(not c.source.startswith("start") for c in same.candidates)
    # a start that fails is no candidate
    failing = check([0.79, 0.5], {"bad": np.array([0.95, 0.95])})
    assert all(not c.source.startswith("start") for c in failing.candidates)


def test_a_start_that_fails_where_it_stands_is_moved_by_a_hair():
    # the user's layout is the disc's centre, which fails exactly there and nowhere else (a
    # tie broken the wrong way): it races moved by at most 1/300, as a failed optimum would
    oracle = _Pinhole([0.5, 0.5])
    X = np.array([[0.5, 0.78], [0.78, 0.5]])
    settings = SMALL.replace(verify_samples=64, error_radius=0.5, verify_candidates=3)
    v = verify_layout(disc_model(), np.array([0.24, 0.5]), X, oracle.simulate(X),
                      oracle.simulate, oracle.validity, settings, starts={"hand": np.full(2, 0.5)})
    moved = [c for c in v.candidates if c.moved_from == "start layout 'hand'"]
    assert len(moved) == 1 and moved[0].source.startswith("start layout 'hand' moved by")
    assert 0 < np.linalg.norm(moved[0].x - 0.5) <= 1 / 300
    assert oracle.simulate(moved[0].x[None])[0].success  # it works where it is placed
    assert v.chosen is moved[0]  # the centre of the disc beats its edges
    # the paper's choice (no race) moves nothing
    plain = verify_layout(disc_model(), np.array([0.24, 0.5]), X, oracle.simulate(X),
                          oracle.simulate, oracle.validity, settings.replace(verify_samples=0),
                          starts={"hand": np.full(2, 0.5)})
    assert not any(c.moved_from for c in (plain.chosen, *plain.candidates))


def test_without_starts_the_exploration_is_the_papers_bit_for_bit():
    """Golden digest of the exploration's samples, taken before starts existed."""
    settings = LearningSettings(
        svm_C_grid=(1.0, 10.0, 100.0, 1000.0), svm_gamma_grid=(0.1, 1.0, 10.0),
        svm_class_weights=(None,), n_initial=64, n_successes=25, exploration_batch=5)
    res = explore(chain_oracle(), settings, np.random.default_rng(0))
    assert (len(res.X), res.n_iterations, res.n_global_successes) == (99, 7, 29)
    assert hashlib.sha256(res.X.tobytes()).hexdigest() == (
        "458f905c39cd4271a24635dbcdf79a40cb97bcc2eb4e8c964abfdefbcc760fbd")
    again = explore(chain_oracle(), settings, np.random.default_rng(0), starts=None)
    np.testing.assert_array_equal(again.X, res.X)
    # with a start, the same Sobol points follow it (no random draw depends on it)
    start = np.full((1, 6), 0.5)
    started = explore(chain_oracle(), settings, np.random.default_rng(0), starts=start)
    np.testing.assert_array_equal(started.X[0], start[0])
    np.testing.assert_array_equal(started.X[1:65], res.X[:64])


def test_invalid_starts_are_left_out_of_the_exploration():
    oracle = ProductOracle(2, {"hit": OracleEvent((), (0, 1), BallRegion((0.5, 0.5), 0.3))},
                           invalid_balls=(((0.2, 0.2), 0.1),))
    settings = SMALL.replace(n_initial=8, n_successes=4)
    res = explore(oracle, settings, np.random.default_rng(0),
                  starts=np.array([[0.2, 0.2], [0.5, 0.5]]))
    np.testing.assert_array_equal(res.X[0], [0.5, 0.5])
    assert not any(np.array_equal(x, [0.2, 0.2]) for x in res.X)


# --- the command ---------------------------------------------------------------------------

SIMPLE = "scenarios/simple.toml"



def test_the_command_starts_from_a_named_layout_in_its_own_run_directory(
        tmp_path, monkeypatch):
    """``rgmcad optimize SIMPLE --budget small --start solved`` as typed (tiny settings),
    in a fresh folder: the default run directory names the start; rerunning resumes."""
    import rgmcad.learning.settings as settings_module

    root = Path(__file__).resolve().parent.parent
    monkeypatch.setattr(settings_module, "budget", lambda name: TINY)
    monkeypatch.chdir(tmp_path)
    argv = ["optimize", str(root / SIMPLE), "--budget", "small", "--start", "solved",
            "--workers", "1", "--json", "-q"]
    code, summary = run_cli(argv)
    run = tmp_path / "runs" / "simple-small-from-solved-s0"
    assert code == 0 and Path(summary["run"]).resolve() == run.resolve()
    assert summary["starts"] and "solved" in summary["starts"]
    sources = [c["source"] for c in summary["verification"]]
    assert "start layout 'solved'" in sources or summary["source"].startswith("start layout")
    # the start was simulated first
    first = json.loads((run / "simulations.jsonl").read_text().splitlines()[0])
    assert np.allclose(first["vector"], summary["starts"]["solved"])
    again_code, again = run_cli(argv)  # finished: the same result
    assert again_code == 0 and again["vector"] == summary["vector"]
    # another start is another run: refused in the same directory
    (tmp_path / "mine.json").write_text('{"values": {"track.x": -0.09}}')
    other = ["optimize", str(root / SIMPLE), "--budget", "small", "--start", "mine.json",
             "--run", str(run), "-q"]
    assert main(other) == 2


@pytest.mark.parametrize("content, why", [
    (None, "unknown layout"),
    ('{"values": {"track.x": 0.5}}', "outside the free ranges"),
    ('{"values": {"track.x": 0.0, "track.z": 0.0, "track.roll": 15}}', "overlap"),
    ("not json{", "cannot read"),
])
def test_a_bad_start_is_refused_in_one_line_before_any_simulation(
        tmp_path, capsys, content, why):
    start = "nonexistent"
    if content is not None:
        start = str(tmp_path / "start.json")
        Path(start).write_text(content)
    run = tmp_path / "run"
    assert main(["optimize", SIMPLE, "--budget", "small", "--start", start,
                 "--run", str(run), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--start" in err[0] and why in err[0], err
    assert not run.exists()


@pytest.mark.parametrize("start", ["", ".", "scenarios"])
def test_a_start_that_names_nothing_is_refused_from_python_too(tmp_path, start):
    # the CLI refuses an empty --start; from Python, "" once ran from the initial layout
    # under the label '' (Path("") is the current folder, which exists)
    from rgmcad.errors import UsageError
    from rgmcad.runs.workflow import optimize_scenario

    with pytest.raises(UsageError, match="--start.*unknown layout"):
        optimize_scenario(SIMPLE, seed=0, run_dir=tmp_path / "run", starts=[start])
    assert not (tmp_path / "run").exists()


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_an_interrupted_run_from_a_start_resumes_to_the_same_result(tmp_path):
    from rgmcad.runs.workflow import optimize_scenario

    def optimize(run):
        return optimize_scenario(SIMPLE, seed=3, budget="small", settings=TINY, run_dir=run,
                                 workers=1, starts=["solved"])

    ref = optimize(tmp_path / "ref").summary
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(tmp_path / "ref" / "settings.json", run)
    lines = (tmp_path / "ref" / "simulations.jsonl").read_bytes().splitlines(keepends=True)
    kept = len(lines) // 3  # a third of the simulations, then a line cut (killed writing)
    (run / "simulations.jsonl").write_bytes(b"".join(lines[:kept]) + lines[kept][:40])
    resumed = optimize(run).summary
    assert resumed["vector"] == ref["vector"] and resumed["source"] == ref["source"]
    assert resumed["simulated_now"] == len(lines) - kept
    # other starts, or none, are another run: this directory is refused for them
    with pytest.raises(RgmcadError, match="settings.json"):
        optimize_scenario(SIMPLE, seed=3, budget="small", settings=TINY, run_dir=run, workers=1)


def test_a_start_that_fails_by_a_hair_in_simulation_is_moved_and_the_report_says_so(tmp_path):
    # the user's layout sits on the edge of success (found by bisecting between `solved` and
    # a failing layout); `optimize --start` races a layout within 1/300 of it that succeeds
    from rgmcad.parts.store import DEFAULT_BUILD_DIR
    from rgmcad.runs.problem import ScenarioProblem
    from rgmcad.runs.starts import resolve_starts
    from rgmcad.runs.workflow import optimize_scenario

    problem = ScenarioProblem(SIMPLE, DEFAULT_BUILD_DIR)
    names = [f.name for f in problem.scenario.free]
    works = resolve_starts(problem.scenario, ["solved"])["solved"]
    rng = np.random.default_rng(0)
    fails = next(x for x in rng.random((50, len(names)))
                 if problem.validity(x[None])[0] and not problem.simulate(x[None])[0].success)
    for _ in range(14):
        mid = (works + fails) / 2
        assert problem.validity(mid[None])[0]
        works, fails = (mid, fails) if problem.simulate(mid[None])[0].success else (works, mid)
    edge = tmp_path / "edge.json"
    edge.write_text(json.dumps({"values": dict(zip(names, map(float, problem.values(fails)),
                                                   strict=True))}))
    x = resolve_starts(problem.scenario, [str(edge)])["edge"]
    assert not problem.simulate(x[None])[0].success  # as the user wrote it, it fails

    run = optimize_scenario(SIMPLE, seed=0, settings=TINY, run_dir=tmp_path / "run", workers=1,
                            starts=[str(edge)], budget="small")
    moved = [c for c in run.summary["verification"]
             if c.get("moved_from") == "start layout 'edge'"]
    assert len(moved) == 1
    y = np.asarray(moved[0]["vector"])
    assert 0 < np.linalg.norm(y - x) <= 1 / 300 and problem.simulate(y[None])[0].success
    report = (tmp_path / "run" / "report.md").read_text()
    assert "The start layout 'edge' failed its own simulation" in report
    assert "The optimum failed" not in report or any(
        c.get("moved_from") == "optimum" for c in run.summary["verification"])
