"""``rgmcad benchmark`` (rgmcad.runs.benchmark): a real benchmark process killed with SIGKILL
resumes to the identical table; our method sets the baselines' budget; bad requests are
refused before any simulation."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rgmcad.cli import main
from rgmcad.errors import RunDirectoryError
from rgmcad.runs.benchmark import PLOT, TABLE_JSON, TABLE_MD, run_benchmark
from tests._support import TINY

QUICK = TINY.replace(verify_samples=32, second_look=False)
"""Ours at its cheapest that still chooses by simulation: the table's bookkeeping is under test,
not the method (its budget sets the baselines', so this makes every row cheaper)."""

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = "scenarios/simple.toml"


def _command(out: Path) -> list[str]:
    return [sys.executable, "-m", "rgmcad.cli", "benchmark", SIMPLE, "--out", str(out),
            "--methods", "b1,b3,cma", "--trials", "2", "--budget-sims", "20",
            "--samples", "1", "--workers", "1", "--json"]


def _without_times(table: dict) -> dict:
    """The table less what a clock measured."""
    out = {k: v for k, v in table.items() if k != "wall_time"}
    out["rows"] = [{k: v for k, v in r.items() if k != "time_s_mean"} for r in table["rows"]]
    return out


def _lines(path: Path) -> int:
    try:
        return path.read_bytes().count(b"\n")
    except OSError:
        return 0


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_a_killed_benchmark_resumes_to_the_identical_table(tmp_path):
    # killed in the middle of the second of three methods: one row finished, one half done,
    # one not begun
    reference = subprocess.run(_command(tmp_path / "whole"), cwd=ROOT, capture_output=True,
                               text=True, timeout=300)
    assert reference.returncode == 0, reference.stderr[-2000:]
    expected = json.loads(reference.stdout)
    out = tmp_path / "killed"
    journal = out / "b3-B20" / "t1" / "simulations.jsonl"  # the GP's second trial, mid-score
    killed = subprocess.Popen(_command(out), cwd=ROOT, stdout=subprocess.DEVNULL,
                              stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while _lines(journal) < 3:
            assert killed.poll() is None and time.monotonic() < deadline, "never got there"
            time.sleep(0.02)
        os.kill(killed.pid, signal.SIGKILL)
        killed.wait()
    finally:
        if killed.poll() is None:
            killed.kill()
            killed.wait()
    assert not (out / TABLE_JSON).exists() and not (out / "b3-B20" / "t1" / "trial.json").exists()
    resumed = subprocess.run(_command(out), cwd=ROOT, capture_output=True, text=True,
                             timeout=300)
    assert resumed.returncode == 0, resumed.stderr[-2000:]
    table = json.loads(resumed.stdout)
    assert _without_times(table) == _without_times(expected)
    assert table == json.loads((out / TABLE_JSON).read_text())
    assert (out / TABLE_MD).read_text().count("\n|---") == 1 and (out / PLOT).stat().st_size > 0
    rows = {r["method"]: r for r in table["rows"]}
    assert set(rows) == {"b1", "b3", "cma"}
    assert all(r["trials"] == 2 and 0 <= r["rho_g_mean"] <= 1 for r in rows.values())
    assert all(r["simulations_mean"] == 20 for m, r in rows.items() if m != "b1")
    assert rows["b1"]["simulations_mean"] <= 20


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_ours_sets_the_budget_and_every_baseline_and_given_layout_is_paired_with_it(tmp_path):
    table = run_benchmark(SIMPLE, tmp_path, methods=("ours", "full", "b1", "b2"), trials=2,
                          samples=1, ours_budget="small", ours_settings=QUICK, workers=1)
    ours, full, b1, b2 = table["rows"]
    assert json.loads((tmp_path / "full" / "t0" / "settings.json").read_text())[
        "settings"]["factorized"] is False  # Fig. 16's variant: one global model
    assert full["budget_sims_mean"] > 0 and "paired_vs_ours" in full
    assert ours["method"] == "ours" and ours["budget_sims_mean"] >= table["budget_sims"]
    assert table["budget_sims"] == int(ours["budget_sims_mean"])  # the floor of the mean
    assert b2["simulations_mean"] <= table["budget_sims"]
    for row in (b1, b2):
        pair = row["paired_vs_ours"]
        diffs = [a - b for a, b in zip(row["rho_g"], ours["rho_g"], strict=True)]
        assert pair["mean_difference"] == pytest.approx(sum(diffs) / 2)
        phys = row["physics_paired_vs_ours"]  # the second column: placement + physics
        diffs = [a - b for a, b in zip(row["physics_rho_g"], ours["physics_rho_g"], strict=True)]
        assert phys["mean_difference"] == pytest.approx(sum(diffs) / 2)
    assert "rho_g placement + physics" in (tmp_path / "benchmark.md").read_text()
    again = run_benchmark(SIMPLE, tmp_path, methods=("ours", "full", "b1", "b2"), trials=2,
                          samples=1, ours_budget="small", ours_settings=QUICK, workers=1)
    assert _without_times(again) == _without_times(table)
    # ours' finished trials are not passed off as those of other settings (--set)
    with pytest.raises(RunDirectoryError, match=r"settings\.verify_samples.*another --out"):
        run_benchmark(SIMPLE, tmp_path, methods=("ours",), trials=2, samples=1,
                      ours_budget="small", ours_settings=QUICK.replace(verify_samples=64),
                      workers=1)

    # a maker's own layouts as rows: the scenario's `solved`, and ours' trial-0 layout given
    # back as a file, each evaluated under every trial's errors like the methods' layouts
    mine = tmp_path / "mine.json"
    mine.write_text((tmp_path / "ours" / "t0" / "layout.json").read_text())
    given = run_benchmark(SIMPLE, tmp_path, methods=("ours", "full", "b1", "b2"), trials=2,
                          samples=1, ours_budget="small", ours_settings=QUICK, workers=1,
                          references=["solved", str(mine)])
    assert _without_times(given)["rows"][:4] == _without_times(table)["rows"]
    solved, mine_row = given["rows"][4:]
    assert (solved["label"], mine_row["label"]) == ("layout 'solved'", "layout 'mine'")
    assert set(given["references"]) == {"solved", "mine"}
    # the layout given back scores exactly what ours' trial 0 scored: the same errors
    assert mine_row["rho_g"][0] == ours["rho_g"][0]
    assert mine_row["physics_rho_g"][0] == ours["physics_rho_g"][0]
    assert solved["rho_g"][0] != solved["rho_g"][1]  # trial 1 draws other errors
    for row in (solved, mine_row):
        diffs = [a - b for a, b in zip(row["rho_g"], ours["rho_g"], strict=True)]
        assert row["paired_vs_ours"]["mean_difference"] == pytest.approx(sum(diffs) / 2)
        assert row["simulations_mean"] is None  # a given layout spends nothing
    text = (tmp_path / "benchmark.md").read_text()
    assert "| layout 'solved' | 2 |" in text and "| layout 'mine' | 2 |" in text

    # one more baseline later, on its own: it gets the budget of ours' finished trials,
    # joins the table, paired with them, and every row measured before stays, unchanged
    more = run_benchmark(SIMPLE, tmp_path, methods=("cma",), trials=2, samples=1, workers=1)
    assert more["budget_sims"] == table["budget_sims"]
    rows = {r["method"]: r for r in _without_times(more)["rows"]}
    assert [r["method"] for r in more["rows"]][:5] == ["ours", "full", "b1", "b2", "cma"]
    assert set(rows) == {"cma", "ours", "full", "b1", "b2", *(r["method"] for r in
                                                                (solved, mine_row))}
    for r in _without_times(given)["rows"]:
        assert rows[r["method"]] == r
    pair = rows["cma"]["paired_vs_ours"]
    diffs = [a - b for a, b in zip(rows["cma"]["rho_g"], ours["rho_g"], strict=True)]
    assert pair["mean_difference"] == pytest.approx(sum(diffs) / 2)
    assert set(more["references"]) == {"solved", "mine"}
    assert "not run again: ours (factorised SPD)" in (tmp_path / "benchmark.md").read_text()


@pytest.mark.slow  # CI's second pass (.ci/run): the default suite stays under 5 minutes
def test_a_row_joins_the_table_only_under_the_same_protocol(tmp_path):
    def bench(*extra):
        argv = ["--build-dir", str(ROOT / "build" / "parts"), "benchmark", str(scenario),
                "--out", str(tmp_path / "b"), "--trials", "2", "--budget-sims", "12",
                "--samples", "1", "--workers", "1", "--json", *extra]
        assert main(argv) == 0
        return json.loads((tmp_path / "b" / TABLE_JSON).read_text())

    scenario = tmp_path / "simple.toml"
    scenario.write_text((ROOT / SIMPLE).read_text())
    bench("--methods", "b1", "--reference", "solved")
    table = bench("--methods", "cma")
    assert [r["method"] for r in table["rows"]][:2] == ["b1", "cma"]
    assert table["rows"][2]["label"] == "layout 'solved'"
    assert [r["method"] for r in bench("--methods", "cma", "--samples", "2")["rows"]] == ["cma"]
    # a given layout spends nothing: its row holds at any budget, B1's does not
    assert [r["label"] for r in bench("--methods", "cma", "--budget-sims", "10")["rows"]] \
        == ["CMA-ES", "layout 'solved'"]
    assert [r["method"] for r in bench("--methods", "cma", "--trials", "3")["rows"]] == ["cma"]
    scenario.write_text(scenario.read_text() + "\n# edited\n")  # another scenario file
    assert [r["method"] for r in bench("--methods", "b2")["rows"]] == ["b2"]


@pytest.mark.parametrize("argv, word", [
    (["benchmark", "simple", "--methods", "b1"], "--budget-sims"),
    (["benchmark", "simple", "--methods", "b1,b9"], "--methods"),
    (["benchmark", "simple", "--methods", "b1,b1"], "--methods"),
    (["benchmark", "simple", "--trials", "0"], "--trials"),
    (["benchmark", "simple", "--samples", "0", "--methods", "b1", "--budget-sims", "5"],
     "--samples"),
    (["benchmark", "simple", "--budget-sims", "0"], "--budget-sims"),
    (["benchmark", "simple", "--reference", "nowhere.json"], "--reference"),
    (["benchmark", "simple", "--reference", "initial", "--reference", "nowhere"],
     "--reference"),
    (["benchmark", "simple", "--set", "verify_samples=-1"], "--set: verify_samples"),
    (["benchmark", "simple", "--set", "nosuch=1"], "not a learning setting"),
])
def test_bad_requests_are_one_line_before_any_simulation(argv, word, tmp_path, capfd):
    assert main(["--build-dir", str(ROOT / "build" / "parts"), *argv,
                 "--out", str(tmp_path / "b")]) == 2
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1 and word in err[0], err
    assert not (tmp_path / "b").exists() or not any((tmp_path / "b").iterdir())
