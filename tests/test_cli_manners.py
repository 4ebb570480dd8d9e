"""What a user meets at the command line: exit statuses, --version, -v/-q, global options
anywhere, choices in any case, "did you mean", the shared part cache, shell completion, and
the numbers and paths the commands print agreeing with what they wrote."""

import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import rgmcad
from rgmcad.cli import main

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = str(ROOT / "scenarios" / "simple.toml")
TINY_SCENARIO = """name = "tiny"
description = "A ball drops on the floor."

[simulation]
duration = 0.5

[objects.floor]
part = "plane"

[objects.ball]
part = "ball"
params = { radius = 0.0117 }
mass = 0.01
pose = { z = 0.05 }
free = { z = [0.02, 0.1] }

[events.ball_falls]
type = "falling"
body = "ball"
"""


def _rgmcad(*args, cwd=None, env=None, timeout=300):
    """``rgmcad ARGS`` in a process of its own, as a user types it."""
    return subprocess.run([sys.executable, "-m", "rgmcad.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


# --- exit statuses ----------------------------------------------------------------------------

@pytest.mark.parametrize("vector, status, outcome", [
    (None, 0, "success"), ("0,1,1", 1, "failure"), ("0,0,0", 1, "invalid")])
def test_simulate_exits_0_on_success_and_1_on_failure_or_invalid(vector, status, outcome,
                                                                 capsys):
    args = ["simulate", SIMPLE, "--json"] + (["--vector", vector] if vector else [])
    assert main(args) == status
    assert json.loads(capsys.readouterr().out)["outcome"] == outcome


def test_simulate_exits_2_on_bad_input(capsys):
    assert main(["simulate", SIMPLE, "--vector", "0.5"]) == 2
    assert main(["simulate", SIMPLE, "--layout", "nowhere"]) == 2


def test_check_exits_1_naming_the_parameter_outside_its_range_and_by_how_much(tmp_path,
                                                                             capsys):
    text = Path(SIMPLE).read_text() + (
        "\n[layouts.too_far]\ntrack = { x = -0.2, z = 0.1, roll = 30 }\n"
        "\n[layouts.steep]\ntrack = { x = -0.1, z = 0.1, roll = 80 }\n")
    path = tmp_path / "s.toml"
    path.write_text(text)
    assert main(["check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "solved: valid, inside the design space" in out
    too_far = next(line for line in out.splitlines() if "too_far:" in line)
    assert "track.x" in too_far and "50 mm below its range [-150, 0] mm" in too_far
    steep = next(line for line in out.splitlines() if "steep:" in line)
    assert "track.roll" in steep and "5 deg above" in steep
    assert main(["check", SIMPLE]) == 0


def test_check_exits_1_when_a_named_layout_is_invalid(tmp_path, capsys):
    path = tmp_path / "s.toml"
    path.write_text(Path(SIMPLE).read_text()
                    + "\n[layouts.sunk]\ntrack = { x = -0.1, z = 0.0, roll = 30 }\n")
    assert main(["check", str(path)]) == 1
    line = next(ln for ln in capsys.readouterr().out.splitlines() if "sunk:" in ln)
    assert "INVALID" in line and "overlap" in line and " mm" in line


# --- version, verbosity, banner ---------------------------------------------------------------

def test_version_is_the_package_version(capsys):
    version = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert rgmcad.__version__ == version
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"rgmcad {version}"


def test_quiet_hides_progress_and_verbose_says_more(capsys):
    assert main(["build", "parts", SIMPLE]) == 0
    assert "building parts" in capsys.readouterr().err
    assert main(["build", "parts", SIMPLE, "-q"]) == 0
    assert capsys.readouterr().err == ""


def _commands(tmp: Path) -> dict[str, list[str]]:
    png = tmp / "a.png"
    return {
        "simulate": ["simulate", "simple", "--json"],
        "check": ["check", "simple"],
        "render": ["render", "simple", "--out", str(png), "--width", "64", "--height", "48"],
        "build parts": ["build", "parts", "simple"],
        "template": ["template", "simple", "--out", str(tmp / "t")],
        "verify-print": ["verify-print", str(ROOT / "docs" / "ballrun_sheet.png")],
        "evaluate": ["evaluate", "simple", "--layout", "solved", "--rho-g", "--samples", "1",
                     "--workers", "2", "--out", str(tmp / "e.png")],
        "export": ["export", "simple", "--out", str(tmp / "s.glb")],
        "supports": ["supports", "simple", "--layout", "solved", "--out", str(tmp / "sup"),
                     "--runs", "0", "--no-step", "--no-template"],
    }


def test_no_pybullet_banner_from_any_command(tmp_path):
    commands = _commands(tmp_path)
    from rgmcad.cli import COMMANDS

    # optimize and benchmark: in the slow test; live serves until stopped (tests/test_live.py)
    assert set(COMMANDS) - set(commands) == {"optimize", "benchmark", "live"}
    for name, args in commands.items():
        done = _rgmcad(*args, cwd=tmp_path)
        assert done.returncode in (0, 1), (name, done.stderr[-2000:])
        assert "pybullet build time" not in done.stdout + done.stderr, name


@pytest.mark.slow
def test_no_pybullet_banner_from_optimize_and_benchmark(tmp_path):
    for args in (["optimize", "simple", "--budget", "small", "--workers", "2"],
                 ["benchmark", "simple", "--methods", "b1", "--trials", "1", "--budget-sims",
                  "20", "--samples", "1", "--ours-budget", "small", "--workers", "2"]):
        done = _rgmcad(*args, cwd=tmp_path, timeout=900)
        assert done.returncode in (0, 1), done.stderr[-2000:]
        assert "pybullet build time" not in done.stdout + done.stderr


# --- parsing: options anywhere, any case, suggestions, completion -----------------------------

def test_build_dir_is_taken_before_or_after_the_command(tmp_path, monkeypatch, capsys):
    a_file = tmp_path / "file"
    a_file.write_text("")
    for args in (["--build-dir", str(a_file / "x"), "check", SIMPLE],
                 ["check", SIMPLE, "--build-dir", str(a_file / "x")]):
        assert main(args) == 2
        assert "--build-dir" in capsys.readouterr().err
    empty = tmp_path / "unused"
    monkeypatch.setenv("RGMCAD_CACHE", str(empty))
    assert main(["check", SIMPLE, "--build-dir", str(ROOT / "build" / "parts")]) == 0
    assert not empty.exists() and "building parts" not in capsys.readouterr().err


def test_choices_are_taken_in_any_case(tmp_path, capsys):
    assert main(["template", SIMPLE, "--out", str(tmp_path), "--paper", "A4", "--json",
                 "--plane", "FLOOR"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["paper"].lower() == "a4" and out["plane"] == "floor"
    from rgmcad.cli import build_parser

    assert build_parser().parse_args(["optimize", SIMPLE, "--budget", "Small"]).budget == "small"


@pytest.mark.parametrize("args, suggestion", [
    (["simulat", SIMPLE], "did you mean simulate?"),
    (["evalute", SIMPLE], "did you mean evaluate?"),
    (["simulate", SIMPLE, "--lyout", "solved"], "did you mean --layout?"),
    (["template", SIMPLE, "--out", "t", "--paper", "a5"], None),
    (["render", SIMPLE, "--out", "x.png", "--widht", "10"], "did you mean --width?"),
    (["--buld-dir", "x", "check", SIMPLE], "did you mean --build-dir?"),
    (["EXPORT", SIMPLE], "did you mean export?"),
    (["build", "part"], "did you mean parts?"),
])
def test_unknown_words_get_one_line_with_the_closest_valid_one(args, suggestion, capsys):
    assert main(args) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    if suggestion:
        assert suggestion in err


def test_shell_completion_script_names_the_commands_and_options(capsys):
    assert main(["--print-completion", "bash"]) == 0
    script = capsys.readouterr().out
    assert "complete" in script and "simulate" in script and "--layout" in script
    done = subprocess.run(["bash", "-n"], input=script, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr  # valid bash


def test_a_closed_pipe_ends_quietly(tmp_path):
    done = subprocess.run(f"{shlex.quote(sys.executable)} -m rgmcad.cli --print-completion zsh"
                          " | head -c 10", shell=True, capture_output=True, text=True)
    assert len(done.stdout) == 10 and "Traceback" not in done.stderr, done.stderr


# --- the part cache, shared across working directories ----------------------------------------

def test_parts_built_in_one_folder_are_reused_from_another(tmp_path):
    scenario = tmp_path / "tiny.toml"
    scenario.write_text(TINY_SCENARIO)
    env = {k: v for k, v in os.environ.items() if k != "RGMCAD_CACHE"}
    env["XDG_CACHE_HOME"] = str(tmp_path / "xdg")  # the default: the user's cache folder
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    first = _rgmcad("check", str(scenario), cwd=tmp_path / "a", env=env)
    assert first.returncode == 0, first.stderr
    cache = tmp_path / "xdg" / "rgmcad" / "parts"
    assert "building parts into" in first.stderr and str(cache) in first.stderr
    assert any(p.name.startswith("ball-") for p in cache.iterdir())
    second = _rgmcad("check", str(scenario), cwd=tmp_path / "b", env=env)
    assert second.returncode == 0 and "building parts" not in second.stderr
    assert not list((tmp_path / "a").iterdir()) and not list((tmp_path / "b").iterdir())
    env["RGMCAD_CACHE"] = str(cache)  # the variable names the same folder
    third = _rgmcad("check", str(scenario), cwd=tmp_path / "b",
                    env={**env, "XDG_CACHE_HOME": str(tmp_path / "elsewhere")})
    assert third.returncode == 0 and "building parts" not in third.stderr


# --- bugs: plot paths, layout names, run directories, counts ----------------------------------

def test_evaluate_without_out_writes_its_plot_beside_the_layout_or_here(tmp_path, monkeypatch,
                                                                       capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "run").mkdir()
    layout = {"scenario": "simple", "values": {"track.x": -0.1, "track.z": 0.1}}
    (tmp_path / "run" / "layout.json").write_text(json.dumps(layout))
    cache = Path(os.environ["RGMCAD_CACHE"])
    before = set(cache.parent.rglob("*.png"))
    for given, plot in (("run/layout.json", "run/layout-robustness.png"),
                        ("solved", "robustness-simple-solved.png")):
        assert main(["evaluate", "simple", "--layout", given, "--rho-g", "--samples", "1", "--workers",
                     "1", "--json"]) == 0
        out = json.loads(capsys.readouterr().out)
        assert out["plot"] == plot and (tmp_path / plot).stat().st_size > 0
        assert out["layout"] == given  # a layout file is named by its path, not "layout"
    assert set(cache.parent.rglob("*.png")) == before  # nothing in the part cache


@pytest.fixture
def tiny_budget(monkeypatch):
    """``--budget small`` on settings small enough for the fast suite."""
    from rgmcad.learning import settings
    from tests._support import TINY

    real = settings.budget
    monkeypatch.setattr(settings, "budget", lambda name: TINY if name == "small" else real(name))


def test_optimize_progress_summary_store_and_next_step_agree(tmp_path, monkeypatch, capsys,
                                                             tiny_budget):
    monkeypatch.chdir(tmp_path)
    status = main(["optimize", "simple", "--budget", "small", "--seed", "3", "--workers", "1"])
    assert status in (0, 1)
    out, err = capsys.readouterr()
    # the simulations the store holds (each distinct layout once)
    run = tmp_path / "runs" / "simple-small-s3"
    records = {}
    for line in (run / "simulations.jsonl").read_text().splitlines():
        record = json.loads(line)
        records[tuple(record["vector"])] = record["outcome"]
    stored, won = len(records), sum(o == "success" for o in records.values())
    # the summary
    n, successes = map(int, re.search(r"(\d+) simulations \((\d+) successes", out).groups())
    assert (n, successes) == (stored, won)
    summary = json.loads((run / "result.json").read_text())
    assert (summary["simulations"], summary["successes"]) == (stored, won)
    # the progress bar's last state
    last = err.replace("\r", "\n").strip().splitlines()[-1]
    assert f"{stored}sim" in last.replace(" ", "") and f"successes={won}" in last
    # the optimised layout as CAD, with the run
    assert (run / "layout.step").stat().st_size > 0 and (run / "layout.glb").stat().st_size > 0
    # the next step, pasted, works (its run directory is the one written)
    step = next(line for line in out.splitlines() if line.startswith("next: "))
    argv = shlex.split(step.removeprefix("next: "))[1:]
    assert str(Path("runs") / "simple-small-s3" / "layout.json") in argv
    capsys.readouterr()
    assert main(argv) in (0, 1)
    assert "layout runs/simple-small-s3/layout.json" in capsys.readouterr().out


def test_documented_optimize_examples_name_the_directories_they_write():
    """Each ``rgmcad optimize`` line of the how-to page "Optimise a layout" with a
    ``# runs/...`` comment writes there, and each ``--layout runs/...`` after it uses a
    directory written above it."""
    from rgmcad.cli import build_parser
    from rgmcad.cli.learning_settings import setting_changes
    from rgmcad.runs.workflow import default_run_dir
    from rgmcad.shipped import scenario_path

    text = (ROOT / "docs" / "how-to" / "optimize.md").read_text()
    blocks = [part.split("```")[0] for part in text.split("```sh")[1:]]
    assert len(blocks) >= 2
    lines = [line for block in blocks for line in block.strip().splitlines()]
    written = set()
    for line in lines:
        command, _, comment = line.partition("#")
        words = shlex.split(command)[2:]  # after "uv run"
        args = build_parser().parse_args(words[1:])
        if args.command == "optimize":
            name = tomllib.loads(scenario_path(args.scenario).read_text())["name"]
            changes = setting_changes(args.changes, args.budget)
            where = args.run_dir or str(default_run_dir(name, args.budget, args.seed,
                                                        args.batch, args.full, args.start,
                                                        args.centering, changes))
            written.add(where.rstrip("/"))
            if comment.strip().startswith("runs/"):
                assert comment.split()[0].rstrip("/") == where, line
        elif getattr(args, "layout", None) and args.layout.startswith("runs/"):
            assert str(Path(args.layout).parent) in written, line
    assert any("small" in w for w in written) and any("-from-" in w for w in written)
