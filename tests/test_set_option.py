"""``rgmcad optimize --set KEY=VALUE``: a learning setting changed from the command line, as a
user types it: the run learns with it, keeps it in a directory of its own, finds it again,
refuses another value in the same directory, and turns bad pairs away in one line."""

import json

import pytest

import rgmcad.learning.settings as settings_module
from tests._support import TINY, cli_output, run_cli

SIMPLE = "scenarios/simple.toml"


@pytest.fixture
def tiny_budget(monkeypatch):
    monkeypatch.setattr(settings_module, "budget", lambda name: TINY)


def test_a_changed_setting_is_learned_with_kept_and_found_again(tiny_budget, tmp_path,
                                                                monkeypatch):
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    monkeypatch.chdir(tmp_path)  # the default run directory is made here
    argv = ["optimize", str(root / SIMPLE), "--budget", "small", "--seed", "3", "--workers", "1",
            "--set", "verify_samples=16", "--set", "second_look=false", "--json", "-q"]
    code, summary = run_cli(argv)
    assert code == 0
    run = tmp_path / "runs" / "simple-small-second_look=false-verify_samples=16-s3"
    assert Path(summary["run"]).resolve() == run.resolve()
    stored = json.loads((run / "settings.json").read_text())["settings"]
    # (second_look = false is how runs made before it existed are stored: left out)
    assert stored["verify_samples"] == 16 and stored.get("second_look", False) is False
    assert stored["n_initial"] == TINY.n_initial  # the rest is the budget's
    # the learner used them: no second look, the race's first stage is 16 errors (TINY: 32)
    assert summary["verify_samples"] == 16 and summary["second_look"] is None
    assert summary["race_stages"][0] == 16
    # the same command again finds the finished run
    code, again = run_cli(argv)
    assert code == 0 and again["vector"] == summary["vector"]
    assert again["simulations"] == summary["simulations"]
    # another value in the same directory is refused, naming the setting
    code, out, err = cli_output([*argv[:8], "--set", "verify_samples=24", "--set",
                                 "second_look=false", "--run", str(run)])
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "settings.verify_samples" in err and "--set" in err


@pytest.mark.parametrize("pair, words", [
    ("nosuch=1", ["nosuch", "not a learning setting", "close_in_copies"]),
    ("close_in_copies=-1", ["close_in_copies", "non-negative integer"]),
    ("close_in_copies=2.5", ["close_in_copies", "whole number"]),
    ("verify_noise=inf", ["verify_noise", "finite"]),
    ("second_look=perhaps", ["second_look", "true or false"]),
    ("optimizer=newton", ["optimizer", "cobyla"]),
    ("svm_C_grid=1,,10", ["svm_C_grid", "comma-separated"]),
    ("centering=always", ["centering", "--centering"]),
    ("exploration_batch=5", ["--batch"]),
    ("second_look_rounds", ["KEY=VALUE"]),
    ("centering_simulations=64", ["verify_samples"]),  # with verify_samples=0 below
])
def test_a_bad_pair_gets_one_line_and_status_2_before_anything_runs(tmp_path, pair, words):
    run = tmp_path / "run"
    code, out, err = cli_output(["optimize", SIMPLE, "--budget", "small", "--run", str(run),
                                 "--set", "verify_samples=0", "--set", pair])
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("rgmcad: error: --set")
    assert all(w in lines[0] for w in words), lines[0]
    assert not run.exists() and not out


def test_a_key_given_twice_is_refused(tmp_path):
    code, _, err = cli_output(["optimize", SIMPLE, "--run", str(tmp_path / "r"), "--set",
                               "verify_samples=16", "--set", "verify_samples=32"])
    assert code == 2 and "verify_samples: given twice" in err


def test_values_read_as_their_settings_type():
    from rgmcad.cli.learning_settings import setting_changes

    changes = setting_changes(["svm_C_grid=0.1, 1,10", "svm_class_weights=none,balanced",
                               "sobol_scramble=NO", "error_radius=0.5", "mi_selection=marginal",
                               "close_in_copies=16"], "default")
    assert changes == {"svm_C_grid": (0.1, 1.0, 10.0), "svm_class_weights": (None, "balanced"),
                       "sobol_scramble": False, "error_radius": 0.5,
                       "mi_selection": "marginal", "close_in_copies": 16}
    from rgmcad.runs.workflow import default_run_dir

    assert default_run_dir("simple", "default", 0, changes=changes).name == (
        "simple-close_in_copies=16-error_radius=0.5-mi_selection=marginal-"
        "sobol_scramble=false-svm_C_grid=0.1,1.0,10.0-svm_class_weights=none,balanced-s0")


def test_a_pair_is_checked_with_the_other_flags_settings(tmp_path):
    # --centering always centres by simulation, judged at the final choice's errors
    code, _, err = cli_output(["optimize", SIMPLE, "--budget", "small", "--run",
                               str(tmp_path / "r"), "--centering", "always", "--set",
                               "verify_samples=0", "--set", "centering_simulations=64"])
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "--set: centering_simulations: needs verify_samples > 0" in err
    assert not (tmp_path / "r").exists()
