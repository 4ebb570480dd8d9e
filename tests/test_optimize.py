"""`rgmcad optimize` and `rgmcad evaluate` on the real simulator: outputs, resuming after an
interruption, independence from the number of workers, refusal of a foreign run directory,
and the pieces they are made of (run store, robustness estimator)."""

import json
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from rgmcad.cli import main
from rgmcad.cli.optimize import show
from rgmcad.errors import RunDirectoryError
from rgmcad.learning import LearningSettings
from rgmcad.runs.problem import ScenarioProblem, SimRecord
from rgmcad.runs.robustness import EPS_GRID, ball_samples, wilson_interval
from rgmcad.runs.store import _ADDED_LATER, SIMULATIONS, RunStore, run_identity
from rgmcad.runs.workflow import optimize_scenario
from rgmcad.sim.run import Outcome
from tests._support import TINY, run_cli

SIMPLE = "scenarios/simple.toml"



def _optimize(run, workers=1, **changes):
    """The workflow of ``rgmcad optimize SIMPLE --seed 3 --budget small`` on the tiny
    settings."""
    return optimize_scenario(SIMPLE, **{"seed": 3, "budget": "small", "settings": TINY,
                                        "run_dir": run, "workers": workers, **changes})


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """One uninterrupted run on one worker: (run dir, its JSON summary)."""
    run = tmp_path_factory.mktemp("reference") / "run"
    done = _optimize(run)
    assert done.verified and not done.finished_before
    return run, done.summary


def test_the_pipeline_runs_on_simple_and_writes_its_outputs(reference):
    run, summary = reference
    assert {"layout", "vector", "probability", "simulations", "wall_time"} <= set(summary)
    for name in ("settings.json", "simulations.jsonl", "model.pkl", "result.json",
                 "layout.json", "start.json", "report.md", "probability_slice.png",
                 "exploration.png"):
        assert (run / name).stat().st_size > 0, name
    lines = (run / SIMULATIONS).read_text().splitlines()
    assert len(lines) <= summary["simulations"]  # repeated vectors are simulated once
    layout = json.loads((run / "layout.json").read_text())
    assert layout["scenario"] == "simple" and len(layout["vector"]) == 3
    assert set(layout["tolerances"]) == {"track.x", "track.z", "track.roll"}
    assert all(down >= 0 and up >= 0 for down, up in layout["tolerances"].values())
    assert set(layout["poses"]) == {"track"} and "roll" in layout["poses"]["track"]
    assert summary["weakest_event"] in summary["event_probabilities"]
    # the report says how the final choice raced, with each candidate's valid copies
    report = (run / "report.md").read_text()
    assert "then twice as many and so on up to 64" in report
    rows = [line for line in report.splitlines() if line.startswith("| simulated sample #")]
    assert rows and all(0 < int(row.split("|")[3]) <= 64 for row in rows)
    # the layout file works as --layout FILE, and the chosen layout was verified
    code, sim = run_cli(["simulate", SIMPLE, "--layout", str(run / "layout.json"), "--json"])
    assert code == 0 and np.allclose(sim["vector"], layout["vector"])
    assert summary["verified"] == (sim["outcome"] == "success")


def test_resuming_an_interrupted_run_gives_the_same_result(reference, tmp_path):
    ref_run, ref = reference
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(ref_run / "settings.json", run)
    data = (ref_run / SIMULATIONS).read_bytes()
    lines = data.splitlines(keepends=True)
    kept = len(lines) // 2
    # half the simulations, then a line cut in the middle (killed while writing)
    (run / SIMULATIONS).write_bytes(b"".join(lines[:kept]) + lines[kept][: len(lines[kept]) // 2])
    resumed = _optimize(run).summary
    assert resumed["vector"] == ref["vector"]
    assert resumed["probability"] == ref["probability"]
    assert resumed["simulations"] == ref["simulations"]
    assert resumed["simulated_now"] == len(lines) - kept
    stored = [json.loads(line) for line in (run / SIMULATIONS).read_text().splitlines()]
    assert len(stored) == len(lines)
    # a finished run is not recomputed
    again = _optimize(run)
    assert again.finished_before and again.summary["vector"] == ref["vector"]


def test_a_finished_run_moved_to_another_folder_names_its_new_place(reference, tmp_path, capsys):
    # the user moves (or copies) a finished run directory and asks for it again there
    ref_run, ref = reference
    moved = tmp_path / "moved"
    shutil.copytree(ref_run, moved)
    again = _optimize(moved)
    assert again.finished_before and again.summary["vector"] == ref["vector"]
    assert again.summary["run"] == str(moved)
    assert again.summary["layout"] == str(moved / "layout.json")
    assert again.summary["start"]["layout"] == str(moved / "start.json")
    show(again.summary, as_json=False)
    out = capsys.readouterr().out
    assert str(moved / "report.html") in out and str(ref_run) not in out


def test_two_workers_give_the_same_result_as_one(reference, tmp_path):
    _, ref = reference
    two = _optimize(tmp_path / "run", workers=2).summary
    assert two["vector"] == ref["vector"] and two["probability"] == ref["probability"]


@pytest.mark.parametrize("change", [{"seed": 4}, {"settings": LearningSettings()}])
def test_a_run_directory_made_with_other_settings_is_refused(reference, change):
    run, _ = reference
    with pytest.raises(RunDirectoryError, match="settings.json"):
        _optimize(run, **change)


def test_the_command_refuses_a_foreign_run_directory_in_one_line(reference, capsys):
    run, _ = reference  # made with the tiny settings, not those of --budget small
    assert main(["optimize", SIMPLE, "--run", str(run), "--seed", "3", "--budget",
                 "small"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "settings.json" in err


def test_the_command_prints_a_summary(reference, capsys):
    run, summary = reference
    show(summary, as_json=False)
    out = capsys.readouterr().out
    assert f"{summary['scenario']}: {summary['layout']}" in out
    assert all(name in out for name in summary["tolerances"])
    assert str(run / "report.md") in out and str(run / "report.html") in out
    show(summary, as_json=True, wall_time=0.5)
    shown = json.loads(capsys.readouterr().out)
    assert shown == {**summary, "wall_time_this_call": 0.5}


def test_a_run_directory_of_another_scenario_is_refused(reference, capsys):
    run, _ = reference
    assert main(["optimize", "scenarios/ballrun.toml", "--run", str(run), "--seed", "3",
                 "--budget", "small"]) == 2
    assert "scenario" in capsys.readouterr().err


def test_evaluate_json(tmp_path):
    code, out = run_cli(["evaluate", SIMPLE, "--layout", "solved", "--rho-g", "--samples", "2",
                      "--workers", "1", "--out", str(tmp_path / "rob.png"), "--json"])
    assert code == 0
    assert {"rho_g", "curve", "simulations"} <= set(out)
    assert len(out["curve"]) == len(EPS_GRID) and all(len(row) == 4 for row in out["curve"])
    assert all(lo <= rho <= hi for _, rho, lo, hi in out["curve"])
    assert out["simulations"] == sum(out["counts"]) <= 2 * len(EPS_GRID)
    assert 0 <= out["rho_g"] <= 1 and (tmp_path / "rob.png").stat().st_size > 0


def test_evaluate_refuses_a_bad_layout(capsys):
    assert main(["evaluate", SIMPLE, "--layout", "nonexistent"]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


# --- the pieces ------------------------------------------------------------------------------


def _record(outcome=Outcome.FAILURE):
    return SimRecord(True, outcome, {"a": (True, 0.1), "b": (None, None)}, 0.05)


def test_run_store_drops_a_half_written_line_and_appends_after_it(tmp_path):
    ident = run_identity("s", "0" * 64, 0, TINY)
    with RunStore(tmp_path, ident) as store:
        store.append(np.array([0.1, 0.2]), _record())
        store.append(np.array([0.3, 0.4]), _record(Outcome.SUCCESS))
    path = tmp_path / SIMULATIONS
    path.write_bytes(path.read_bytes() + b'{"i": 2, "vector": [0.5, 0.')
    with RunStore(tmp_path, ident) as store:
        assert store.n_lines == 2
        assert store.lookup(np.array([0.3, 0.4])).outcome is Outcome.SUCCESS
        assert store.lookup(np.array([0.3, 0.40000000000000002])) is not None  # same double
        assert store.lookup(np.array([0.3, 0.4000001])) is None
        store.append(np.array([0.5, 0.6]), _record())
    rows = [json.loads(line) for line in path.read_text().splitlines()]
    assert [r["i"] for r in rows] == [0, 1, 2] and rows[2]["vector"] == [0.5, 0.6]


def test_run_store_refuses_other_settings_and_a_second_user(tmp_path):
    import subprocess
    import sys

    with RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY)):
        with pytest.raises(RunDirectoryError, match=r"this process \(pid \d+\) has this run "
                           "directory open already"):
            RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY))
        # refusing here did not release the lock: another process is refused too
        other = subprocess.run(
            [sys.executable, "-c", "import sys; from rgmcad.runs.lock import DirectoryLock; "
             "DirectoryLock(sys.argv[1])", str(tmp_path)], capture_output=True, text=True)
        assert other.returncode == 1 and "another rgmcad process" in other.stderr
    with pytest.raises(RunDirectoryError, match="n_initial"):
        RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY.replace(n_initial=41)))
    # n_jobs changes the speed, not the result
    RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY.replace(n_jobs=2))).close()
    # a setting the run directory lacks (made by an older rgmcad) is named, even when the
    # command's value is None
    path = tmp_path / "settings.json"
    stored = json.loads(path.read_text())
    stored["settings"].pop("n_initial")
    stored["settings"]["retired_option"] = None
    path.write_text(json.dumps(stored))
    with pytest.raises(RunDirectoryError) as refused:
        RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY))
    assert "settings.n_initial: run has nothing, command asks 40" in str(refused.value)
    assert "settings.retired_option: run has None, command asks nothing" in str(refused.value)


def test_a_run_directory_made_before_a_setting_was_added_still_resumes(tmp_path):
    # what older rgmcad wrote had no `unmodelled_at`; its value then was "start"
    older = run_identity("s", "0" * 64, 0, TINY.replace(unmodelled_at="start"))
    assert "unmodelled_at" not in older["settings"]
    assert run_identity("s", "0" * 64, 0, TINY)["settings"]["unmodelled_at"] == "median"
    (tmp_path / "settings.json").write_text(json.dumps(older))
    RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY.replace(unmodelled_at="start"))).close()
    with pytest.raises(RunDirectoryError, match="unmodelled_at: run has nothing, command asks "
                       "'median'"):
        RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY.replace(unmodelled_at="median")))


OLDER_SETTINGS = Path(__file__).parent / "data" / "older_settings"


@pytest.mark.parametrize("budget_name", ["default", "small"])
@pytest.mark.parametrize("snapshot", sorted(OLDER_SETTINGS.glob("*.json")), ids=lambda p: p.stem)
def test_a_run_directory_of_an_older_rgmcad_resumes_after_an_upgrade(tmp_path, snapshot,
                                                                     budget_name):
    # each file: the settings.json that rgmcad wrote, for each budget, just before a setting
    # was added. The settings that run ran with are the ones it names plus, for every setting
    # added since, the value that gives the code before it; today's rgmcad, asked for those,
    # must open the directory (a setting added without saying which value gives the code
    # before would refuse every older run directory)
    stored = json.loads(snapshot.read_text())[budget_name]
    named = {k: tuple(v) if isinstance(v, list) else v for k, v in stored["settings"].items()}
    ran = LearningSettings(**{**_ADDED_LATER, **named})
    (tmp_path / "settings.json").write_text(json.dumps(stored))
    RunStore(tmp_path, run_identity(stored["scenario"], stored["scenario_sha256"],
                                    stored["seed"], ran)).close()


class _LoggingPool:
    """Executor stand-in whose workers' context is ``context``: runs ``map_context`` lazily,
    as a pool hands results back, and logs which function each call ran."""

    workers = 2

    def __init__(self, context):
        self.context = context
        self.calls = []

    def map_context(self, fn, items):
        self.calls.append(fn.__name__)
        return (fn(self.context, item) for item in list(items))


class _Plane:
    """A 2-D problem stand-in: valid where x0 < 0.9, success where x0 + x1 > 1."""

    dimension = 2
    event_parents = {"a": ()}
    any_joins = frozenset()

    def validity(self, X):
        return np.atleast_2d(X)[:, 0] < 0.9

    def simulate_one(self, x):
        ok = bool(x[0] + x[1] > 1)
        return SimRecord(True, Outcome.SUCCESS if ok else Outcome.FAILURE, {"a": (ok, 0.1)},
                         0.01)


def test_batches_in_flight_are_stored_in_order_and_validity_is_tested_here_meanwhile(tmp_path):
    from rgmcad.runs.store import RecordedProblem

    pool = _LoggingPool(_Plane())
    with RunStore(tmp_path, run_identity("s", "0" * 64, 0, TINY)) as store:
        recorded = RecordedProblem(_Plane(), store, pool)
        first = recorded.submit(np.array([[0.2, 0.3], [0.6, 0.7]]))
        second = recorded.submit(np.array([[0.6, 0.7], [0.1, 0.95]]))  # one vector again
        assert recorded.validity(np.array([[0.5, 0.5], [0.95, 0.5]])).tolist() == [True, False]
        assert pool.calls == ["simulate_layout_task"] * 2  # tested here, not in the pool
        assert [lab.success for lab in first()] == [False, True]
        assert [lab.success for lab in second()] == [True, True]
        recorded.validity(np.array([[0.5, 0.5], [0.95, 0.5]]))
        assert pool.calls[-1] == "validity_task"  # nothing in flight: the pool tests
    rows = [json.loads(line) for line in (tmp_path / SIMULATIONS).read_text().splitlines()]
    assert [r["vector"] for r in rows] == [[0.2, 0.3], [0.6, 0.7], [0.6, 0.7], [0.1, 0.95]]
    assert [r["outcome"] for r in rows] == ["failure", "success", "success", "success"]


def test_stored_records_are_plain_words_and_old_lines_read_back(tmp_path):
    ident = run_identity("s", "0" * 64, 0, TINY)
    with RunStore(tmp_path, ident) as store:
        store.append(np.array([0.1, 0.2]), _record(Outcome.SUCCESS))
    line = (tmp_path / SIMULATIONS).read_text()
    assert line == ('{"i": 0, "vector": [0.1, 0.2], "valid": true, "outcome": "success", '
                    '"events": {"a": [true, 0.1], "b": [null, null]}, "seconds": 0.05}\n')
    # a line as rgmcad wrote it before outcomes were enums
    old = {"i": 1, "vector": [0.3, 0.4], "valid": False, "outcome": "invalid",
           "events": {"a": [None, None]}, "seconds": 0.001}
    with open(tmp_path / SIMULATIONS, "a") as f:
        f.write(json.dumps(old) + "\n")
    with RunStore(tmp_path, ident) as store:
        record = store.lookup(np.array([0.3, 0.4]))
        assert record.outcome is Outcome.INVALID and not record.label().valid
        assert store.lookup(np.array([0.1, 0.2])).label().success


def test_scenario_problem_pickles_small_and_matches_the_simulator():
    import pickle

    problem = ScenarioProblem(SIMPLE)
    blob = pickle.dumps(problem)
    assert len(blob) < 2000
    clone = pickle.loads(blob)
    x = np.array([0.5, 0.5, 0.5])
    assert clone.simulate_one(x).events == problem.simulate_one(x).events
    assert problem.validity(np.array([x]))[0] == (problem.penetration(x) == 0)


def test_ball_samples_are_uniform_in_the_ball_inside_the_cube():
    rng = np.random.default_rng(0)
    x = np.array([0.05, 0.5, 0.5])
    Y = ball_samples(x, 0.2, 4000, rng)
    assert len(Y) == 4000
    assert np.all(np.linalg.norm(Y - x, axis=1) <= 0.2) and np.all((Y >= 0) & (Y <= 1))
    # uniform in the ball cut by the face x0 = 0: P(|y - x| <= 0.1) = V(inner ball minus its
    # cap of height 0.05) / V(ball minus its cap of height 0.15) = 0.1543
    inner = np.mean(np.linalg.norm(Y - x, axis=1) <= 0.1)
    assert abs(inner - 0.1543) < 0.02


def test_wilson_interval_covers_and_is_narrow_for_large_counts():
    low, high = wilson_interval([0, 5, 50, 500], [10, 10, 100, 1000])
    assert low[0] == 0 and 0.2 < high[0] < 0.32
    assert low[1] < 0.5 < high[1]
    assert high[3] - low[3] < 0.07
    low, high = wilson_interval([0], [0])
    assert (low[0], high[0]) == (0.0, 1.0)


# Two valid BALLRUN layouts: whether B is simulated first must not change A's simulation.
_BALLRUN_A = [0.29057695902884007, 0.28684365190565586, 0.10656715836375952,
              0.33929358795285225, 0.8954978417605162, 0.1586164440959692, 0.7111092647537589,
              0.38492103945463896]
_BALLRUN_B = [0.6217232290655375, 0.9346422553062439, 0.8769307704642415, 0.30552376341074705,
              0.9169419407844543, 0.05207661725580692, 0.2744410736486316, 0.8762572268024087]


def test_a_simulation_does_not_depend_on_what_the_process_simulated_before():
    import subprocess
    import sys

    code = ("import json, sys, numpy as np\n"
            "from rgmcad.runs.problem import ScenarioProblem\n"
            "p = ScenarioProblem('scenarios/ballrun.toml')\n"
            "out = [p.simulate_one(np.array(v)).events for v in json.loads(sys.argv[1])][-1]\n"
            "print(json.dumps(out))\n")
    runs = [subprocess.run([sys.executable, "-c", code, json.dumps(seq)], capture_output=True,
                           text=True, check=True).stdout
            for seq in ([_BALLRUN_A], [_BALLRUN_B, _BALLRUN_A])]
    assert runs[0] == runs[1]


def test_full_learns_one_model_for_the_whole_graph_in_its_own_run_directory(reference, tmp_path):
    """``rgmcad optimize --full``: the paper's Fig. 16 variant, beside the factorised run."""
    from rgmcad.learning.factorize import GLOBAL_EVENT
    from rgmcad.runs.workflow import default_run_dir

    _, factorised = reference
    assert GLOBAL_EVENT not in factorised["event_probabilities"]
    full = _optimize(tmp_path / "full", full=True).summary
    assert list(full["event_probabilities"]) == [GLOBAL_EVENT]
    assert default_run_dir("simple", "default", 0, full=True).name == "simple-full-s0"
    assert default_run_dir("simple", "small", 2, 40, full=True).name == "simple-small-b40-full-s2"
    assert default_run_dir("simple", "small", 0, centering="always").name == (
        "simple-small-centring-always-s0")
    assert default_run_dir("simple", "small", 0, centering="auto").name == "simple-small-s0"


def test_the_command_line_full_option_reaches_the_learner(tmp_path, monkeypatch):
    """``rgmcad optimize SIMPLE --budget small --full`` as typed (on the tiny settings)."""
    import rgmcad.learning.settings as settings_module
    from rgmcad.learning.factorize import GLOBAL_EVENT

    monkeypatch.setattr(settings_module, "budget", lambda name: TINY)
    code, summary = run_cli(["optimize", SIMPLE, "--budget", "small", "--seed", "3", "--full",
                          "--run", str(tmp_path / "run"), "--json", "-q"])
    assert code == 0 and list(summary["event_probabilities"]) == [GLOBAL_EVENT]


def _far_track(tmp_path, free: str):
    """simple.toml with the track's free ranges replaced."""
    text = open(SIMPLE).read()
    given = "free = { x = [-0.15, 0.0], z = [0.0, 0.15], roll = [15, 75] }"
    assert given in text
    path = tmp_path / "far.toml"
    path.write_text(text.replace(given, free))
    return path


def test_a_run_where_nothing_succeeds_says_what_to_do(tmp_path, monkeypatch, capsys):
    """``rgmcad optimize`` on a scenario whose free ranges put the track 0.8 m from the
    dominoes, low and flat (the ball never reaches them): exit status 1 and one warning line
    naming ``--start``."""
    import rgmcad.learning.settings as settings_module

    hopeless = _far_track(tmp_path, "free = { x = [-0.9, -0.8], z = [0.04, 0.08], "
                                    "roll = [15, 25] }")
    monkeypatch.setattr(settings_module, "budget", lambda name: TINY)
    code = main(["optimize", str(hopeless), "--budget", "small", "--run",
                 str(tmp_path / "run"), "--workers", "1"])
    out, err = capsys.readouterr()
    assert code == 1
    assert "unverified" in out
    warning = [line for line in err.splitlines() if line.startswith("warning: no layout")]
    assert len(warning) == 1 and "--start LAYOUT" in warning[0]


def test_free_ranges_where_every_layout_overlaps_are_refused_in_one_line(tmp_path, capsys):
    """The track at most 1 cm up and tilted: it cuts the floor in every layout. One line
    naming the file and ``free``, exit status 2, no traceback."""
    overlapping = _far_track(tmp_path, "free = { x = [-0.9, -0.8], z = [0.0, 0.01], "
                                       "roll = [15, 20] }")
    code = main(["optimize", str(overlapping), "--budget", "small", "--run",
                 str(tmp_path / "run"), "--workers", "1", "-q"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert str(overlapping) in err[0] and ": free: " in err[0] and "--vector 0.5,0.5,0.5" in err[0]
    # nothing was simulated: no run directory is left behind to puzzle over (a folder the
    # user made beforehand stays, and so does one whose journal holds simulations)
    assert not (tmp_path / "run").exists()
    mine = tmp_path / "mine"
    mine.mkdir()
    assert main(["optimize", str(overlapping), "--budget", "small", "--run", str(mine),
                 "--workers", "1", "-q"]) == 2
    assert mine.is_dir()


def test_evaluate_warns_when_a_layout_fails_even_placed_almost_exactly(tmp_path, capsys):
    # a layout on the edge of what works, found as a user would: the track's roll raised
    # until the run fails (simple: it works below about 0.42 of the range), the edge then
    # bisected by `rgmcad simulate`; found on this machine, so it is an edge wherever the
    # test runs (a fixed knife-edge layout stopped being one on another CPU)
    def works(roll):
        code, out = run_cli(["simulate", "simple", "--vector", f"{1 / 3!r},{2 / 3!r},{roll!r}",
                             "--json", "-q"])
        assert code == (0 if out["outcome"] == "success" else 1)
        return code == 0

    low, high = 0.25, 1.0
    assert works(low) and not works(high)
    while high - low > 1e-5:
        low, high = ((low + high) / 2, high) if works((low + high) / 2) else (low, (low + high) / 2)
    layout = tmp_path / "edge.json"
    layout.write_text(json.dumps({"scenario": "simple", "vector": [1 / 3, 2 / 3, low]}))
    argv = ["evaluate", "simple", "--rho-g", "--samples", "10", "--physics", "off", "--workers", "1",
            "--out", str(tmp_path / "r.png"), "-q", "--layout"]
    assert main([*argv, str(layout)]) == 0
    warning = re.search(r"warning: only (\d+) of the 10 layouts within 1/300 of this one "
                        r"succeeded: it may fail even when placed exactly",
                        capsys.readouterr().out)
    assert warning and 1 <= int(warning.group(1)) <= 9
    assert main([*argv, "solved"]) == 0  # far from the edge, every one works: no warning
    assert "warning" not in capsys.readouterr().out


def test_a_finished_run_asked_for_with_another_hand_is_refused_not_shown(reference, tmp_path):
    # the user optimised for +-2 mm, then asks the same run for +-6 mm: its figures and its
    # choice are for +-2 mm, so it says so and names the command that answers the question
    from rgmcad.errors import UsageError
    from rgmcad.runs.hand import Hand

    ref_run, ref = reference
    run = tmp_path / "run"
    shutil.copytree(ref_run, run)
    with pytest.raises(UsageError) as error:
        _optimize(run, hand=Hand(6.0, 6.0))
    assert error.value.where == "--hand" and "rgmcad evaluate" in str(error.value)
    assert "+-2 mm" in str(error.value) and str(run / "layout.json") in str(error.value)
    with pytest.raises(UsageError) as error:
        _optimize(run, physics=None)
    assert error.value.where == "--physics" and "friction +-20%" in str(error.value)
    assert _optimize(run).summary["vector"] == ref["vector"]  # as it was made: shown
    assert _optimize(run, hand=None).finished_before  # no hand asked for: nothing to compare
