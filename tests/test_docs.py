"""The documentation site builds in strict mode (a broken link fails it), and its reference
pages follow the code: every option of every command is on the page, and an option, a scenario
number or a part family the code gains shows up without anyone writing it down."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rgmcad.cli import build_parser
from rgmcad.parts.family import load_families
from rgmcad.reference import PAGES
from rgmcad.reference import cli as cli_page
from rgmcad.reference import parts as parts_page
from rgmcad.reference import runs as runs_page
from rgmcad.reference import scenario as scenario_page
from rgmcad.reference.text import cell
from rgmcad.scene import schema

ROOT = Path(__file__).resolve().parent.parent


def build_site(config: Path, site: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file",
                           str(config), "--site-dir", str(site)], capture_output=True, text=True,
                          cwd=config.parent, timeout=300,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})


def test_the_site_builds_in_strict_mode_with_the_generated_pages(tmp_path):
    done = build_site(ROOT / "mkdocs.yml", tmp_path / "site")
    assert done.returncode == 0, done.stderr[-3000:]
    for path in PAGES:
        html = tmp_path / "site" / path.removesuffix(".md") / "index.html"
        assert html.is_file(), path
    cli_html = (tmp_path / "site" / "reference" / "cli" / "index.html").read_text()
    assert "--budget" in cli_html and "--print-completion" in cli_html
    assert (tmp_path / "site" / "decisions" / "index.html").is_file()
    assert not (ROOT / "docs" / "reference").exists()  # generated into the build only


def test_a_broken_link_fails_the_build(tmp_path):
    copy = tmp_path / "src"
    shutil.copytree(ROOT / "docs", copy / "docs", ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copy(ROOT / "mkdocs.yml", copy / "mkdocs.yml")
    for watched in ("rgmcad", "parts"):  # the config watches them; they must exist
        (copy / watched).symlink_to(ROOT / watched)
    tutorial = copy / "docs" / "tutorial.md"
    tutorial.write_text(tutorial.read_text() + "\nSee [the missing page](no-such-page.md).\n")
    done = build_site(copy / "mkdocs.yml", tmp_path / "site")
    assert done.returncode != 0
    assert "no-such-page.md" in done.stderr


def _leaf_commands(parser, words=()):
    """(name, parser) of every runnable command, found by walking argparse's own structures."""
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if words and not subs:
        yield " ".join(words), parser
    for action in subs:
        for name, sub in action.choices.items():
            yield from _leaf_commands(sub, (*words, name))


def _section(page: str, heading: str) -> str:
    start = page.index(heading)
    end = page.find("\n## ", start + 1)
    return page[start:] if end < 0 else page[start:end]


def test_the_cli_page_names_every_option_of_every_command():
    parser = build_parser()
    page = cli_page.page(parser)
    global_section = _section(page, "## Global options")
    top_flags = {s for a in parser._actions for s in a.option_strings}
    for s in top_flags:
        assert f"{s}" in global_section, s
    commands = dict(_leaf_commands(parser))
    assert {"simulate", "optimize", "build parts", "export"} <= set(commands)
    for name, sub in commands.items():
        section = _section(page, f"## rgmcad {name} {{#")
        for action in sub._actions:
            if action.help == argparse.SUPPRESS:
                continue
            if not action.option_strings:
                assert action.dest in section, (name, action.dest)
            elif not set(action.option_strings) <= top_flags:  # global ones: listed once
                assert all(s in section for s in action.option_strings), (name, action)
            own = not action.option_strings or not set(action.option_strings) <= top_flags
            if own and action.help and not set("%|<") & set(action.help):  # as written
                assert action.help in section, (name, action.help)


def test_a_new_option_shows_up_and_a_hidden_one_does_not():
    parser = build_parser()
    optimize = dict(_leaf_commands(parser))["optimize"]
    optimize.add_argument("--glue-time", metavar="SECONDS", type=float, default=12.5,
                          help="how long the glue sets (default %(default)s s)")
    optimize.add_argument("--secret-knob", help=argparse.SUPPRESS)
    section = _section(cli_page.page(parser), "## rgmcad optimize {#")
    assert "| `--glue-time SECONDS` | `12.5` | how long the glue sets (default 12.5 s) |" in section
    assert "--secret-knob" not in section


def test_a_new_scenario_number_shows_up(monkeypatch):
    monkeypatch.setitem(schema.SIMULATION, "glue_strength",
                        schema.Number("N", 0, 50, usual=(0, 20), slip=("", "kilonewtons?")))
    page = scenario_page.page()
    assert "| `[simulation]` | `glue_strength` | a number (N), 0 <= x <= 50 | up to 20 N |" in page


def test_a_scenario_key_without_its_prose_fails_with_its_name(monkeypatch):
    monkeypatch.setattr(scenario_page, "TOP_KEYS", (*scenario_page.TOP_KEYS, "gadgets"))
    with pytest.raises(ValueError, match="gadgets"):
        scenario_page.page()


def test_the_scenario_and_event_pages_cover_every_key():
    page, events = scenario_page.page(), scenario_page.events_page()
    for where, keys, spec in schema.rows():
        assert f"| {where} | {keys} | {cell(spec.describe())} |" in page
    for name, kind in scenario_page.EVENT_TYPES.items():
        section = _section(events, f"### `{name}`")
        assert all(f"`{k}`" in section for k in (*kind.roles, *kind.params))


def test_a_new_part_family_shows_up_with_its_parameters(tmp_path):
    (tmp_path / "gear.py").write_text('''"""Gear: a toy gear.

Frame: the origin is the gear's centre.
"""

from dataclasses import dataclass, field

from rgmcad.parts.family import Family


@dataclass(frozen=True)
class Params:
    radius: float  # m, to the tips of the teeth
    teeth: int = 12  # count of teeth
    helix: float = field(default=30.0, metadata={"unit": "deg", "range": (0.0, 45.0)})  # lean

    def check(self):
        return None if self.radius > 0 else "radius must be > 0"


FAMILY = Family(name="gear", params=Params, build=None, collision=None,
                description="a flat gear with straight teeth")
''')
    page = parts_page.page(load_families(tmp_path))
    assert "## `gear` {#gear}" in page and "a flat gear with straight teeth" in page
    assert "Frame: the origin is the gear's centre." in page
    assert "| `radius` | a number (m), -100 to 100; 0 or at least 1e-05 m in size | needed | " \
           "m, to the tips of the teeth |" in page
    assert "| `teeth` | an integer, -1000 to 1000 | `12` | count of teeth |" in page
    assert "| `helix` | a number (deg), 0 to 45 | `30` | lean |" in page
    assert "* radius must be > 0" in page


def test_the_shipped_part_families_are_all_on_their_page():
    page = parts_page.page()
    for name, family in load_families().items():
        assert f"## `{name}`" in page and family.description in page


def test_the_run_directory_page_names_every_file_the_code_names():
    page = runs_page.page()
    names = [name for name, _, _ in runs_page.files()]
    assert len(names) == len(set(names))
    assert {"settings.json", "simulations.jsonl", "result.json", "layout.json", "report.html",
            "layout.step"} <= set(names)
    assert all(f"| `{name}` |" in page for name in names)


@pytest.mark.slow
def test_a_real_run_directory_holds_only_files_the_page_names(tmp_path):
    run = tmp_path / "run"
    done = subprocess.run([sys.executable, "-m", "rgmcad.cli", "optimize", "simple", "--budget",
                           "small", "--run", str(run), "--hand", "off", "-q"],
                          capture_output=True, text=True, cwd=ROOT, timeout=1200)
    assert done.returncode in (0, 1), done.stderr[-3000:]
    held = sorted(p.relative_to(run).as_posix() for p in run.rglob("*") if p.is_file())
    page = runs_page.page()
    assert held and not [name for name in held if f"`{name}`" not in page]


def test_a_results_table_is_made_from_its_json_and_a_page_cannot_lose_one(tmp_path):
    # the built-by-hand page carries a marker, not a copy: the table follows the file
    import json as _json

    from rgmcad.reference.results import fill, hand_table

    page = (ROOT / "docs" / "results" / "hand.md").read_text()
    assert "<!-- table: docs/hand-acceptance.json -->" in page
    results = _json.loads((ROOT / "docs" / "hand-acceptance.json").read_text())
    filled = fill(page, ROOT)
    assert hand_table(results) in filled and "<!-- table:" not in filled
    first = next(iter(results.values()))
    first["optimum"]["rate"], first["optimum"]["interval"] = 0.5, [0.4, 0.6]
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "hand-acceptance.json").write_text(_json.dumps(results))
    assert "50 % [40, 60]" in fill(page, tmp_path)  # a new measurement, a new table
    with pytest.raises(ValueError, match="no table is made from docs/other.json"):
        fill("<!-- table: docs/other.json -->", ROOT)


def _benchmark(revision, ours=0.6, cma=0.5, physics=(0.4, 0.2)):
    def row(method, label, rho, phys, sims):
        return {"method": method, "label": label, "trials": 3, "rho_g_mean": rho,
                "rho_g_se": 0.01, "physics_rho_g_mean": phys, "physics_rho_g_se": 0.02,
                "simulations_mean": sims, "time_s_mean": None if sims is None else 9.0,
                "vectors": [[0.5] * 8] * 3}
    table = {"scenario": "ballrun", "budget_sims": 1724, "seeds": [0, 1, 2],
             "samples_per_radius": 20, "physics": {"friction": 0.2, "mass": 0.1,
                                                   "restitution": 0.2},
             "rows": [row("ours", "ours (factorised SPD)", ours, physics[0], 1711),
                      row("cma", "CMA-ES", cma, physics[1], 1690),
                      row("solved", "layout 'solved'", 0.45, 0.3, None)]}
    if revision:
        table["physics_revision"] = revision
    return table


def test_a_benchmark_table_says_which_physics_measured_it(tmp_path):
    # the user's view: a results page shows the benchmark's rows and, under them, the file and
    # the physics it was measured under; figures of superseded physics carry a warning
    import json as _json

    from rgmcad.reference.results import fill
    from rgmcad.sim.revision import PHYSICS_REVISION

    runs = tmp_path / "docs" / "results" / "runs"
    runs.mkdir(parents=True)
    (runs / "benchmark-ballrun.json").write_text(_json.dumps(_benchmark(PHYSICS_REVISION)))
    page = fill("<!-- table: docs/results/runs/benchmark-ballrun.json -->", tmp_path)
    assert "| CMA-ES | 3 | 0.500 +- 0.010 |" in page and "B = 1,724 simulations" in page
    assert "measured under the current physics" in page and "warning" not in page
    (runs / "benchmark-ballrun.json").write_text(_json.dumps(_benchmark("2026-12-01")))
    page = fill("<!-- table: docs/results/runs/benchmark-ballrun.json -->", tmp_path)
    assert '!!! warning "Measured under earlier physics"' in page and "2026-12-01" in page
    (runs / "benchmark-ballrun.json").write_text(_json.dumps(_benchmark(None)))
    assert "before 2026-12-08" in fill(
        "<!-- table: docs/results/runs/benchmark-ballrun.json -->", tmp_path)


def test_the_glance_compares_ours_with_the_best_baseline_of_every_benchmark(tmp_path):
    import json as _json

    from rgmcad.reference.results import fill
    from rgmcad.sim.revision import PHYSICS_REVISION

    runs = tmp_path / "docs" / "results" / "runs"
    runs.mkdir(parents=True)
    ballrun = _benchmark(PHYSICS_REVISION)
    ballrun["rows"].append({**ballrun["rows"][0], "method": "full", "label": "ours, one model",
                            "rho_g_mean": 0.9})  # ours too (Fig. 16), not a baseline
    (runs / "benchmark-ballrun.json").write_text(_json.dumps(ballrun))
    other = _benchmark(PHYSICS_REVISION, ours=0.3, cma=0.6, physics=(0.2, 0.25))
    other["scenario"] = "teapot"
    (runs / "benchmark-teapot.json").write_text(_json.dumps(other))
    page = fill("<!-- table: docs/results/runs/benchmark-*.json -->", tmp_path)
    lines = {line.split(" | ")[0]: line for line in page.splitlines() if line.startswith("| ")}
    assert "0.600 / 0.400 (3 trials) | CMA-ES 0.500 / CMA-ES 0.200 | 1.20x / 2.00x" \
        in lines["| ballrun"]
    assert "0.50x / 0.80x" in lines["| teapot"]  # a loss reads as a loss
    assert "layout 'solved' 0.450 / 0.300" in lines["| ballrun"]  # a given layout: no baseline
    assert "benchmark-ballrun.json`, `docs/results/runs/benchmark-teapot.json" in page


def test_a_section_from_the_log_is_flagged_when_the_physics_moves_on():
    from rgmcad.reference.results import fill
    from rgmcad.sim.revision import PHYSICS_REVISION

    now = fill(f"<!-- measured under the physics of {PHYSICS_REVISION} -->", ROOT)
    assert "current physics" in now and "warning" not in now
    old = fill("<!-- measured under the physics of 2026-12-04 -->", ROOT)
    assert old.startswith('!!! warning "Measured under earlier physics"') and "2026-12-04" in old
