"""The tutorial as a reader follows it: its scenario saved as the file it names, each of its
shell commands run in order in an empty folder (as ``uv run`` would: the installed
``rgmcad``), and every line of the output it shows found in what the command printed (wall
times aside). Slow (about a minute): CI runs it after the suite (``.ci/run``)."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
TUTORIAL = ROOT / "docs" / "tutorial.md"
BLOCK = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)
WALL = re.compile(r"\bin \d+(\.\d+)? s\b")  # "simulated in 0.02 s", "done in 0.4 s": wall time


def steps(text: str) -> tuple[str, list[tuple[str, str]]]:
    """(the scenario, [(shell block, the output block shown after it, or "")])."""
    blocks = [(lang, body) for lang, body in BLOCK.findall(text)]
    scenario = next(body for lang, body in blocks if lang == "toml")
    out = []
    for lang, body in blocks:
        if lang == "sh":
            out.append([body, ""])
        elif lang == "" and out and not out[-1][1]:
            out[-1][1] = body
    return scenario, [tuple(s) for s in out]


def normalised(text: str) -> str:
    return WALL.sub("in T s", text)


@pytest.mark.slow
def test_the_tutorial_runs_as_written_and_shows_what_it_says(tmp_path):
    scenario, commands = steps(TUTORIAL.read_text())
    name = re.search(r"Save this as `([^`]+)`", TUTORIAL.read_text()).group(1)
    (tmp_path / name).write_text(scenario)
    rgmcad = Path(sys.executable).parent / "rgmcad"
    env = {**os.environ, "COLUMNS": "200"}
    assert commands, "the tutorial runs no command"
    for block, shown in commands:
        script = block.replace("uv run rgmcad", f'"{rgmcad}"')
        done = subprocess.run(["bash", "-e", "-c", script], cwd=tmp_path, env=env,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, f"{block.strip()}\n{done.stderr[-2000:]}"
        printed = normalised(done.stdout + done.stderr)
        for line in shown.splitlines():
            assert normalised(line).strip() in printed, (
                f"{block.strip()}: the tutorial shows\n{line}\nbut it printed\n{done.stdout}")
    for made in ("first.html", "runs/first-s0/layout.json", "runs/first-s0/report.html",
                 "runs/first-s0/template/template.pdf", "runs/first-s0/template/template.svg"):
        assert (tmp_path / made).stat().st_size > 0, made


def test_the_tutorial_is_read_as_the_test_above_reads_it():
    scenario, commands = steps(TUTORIAL.read_text())
    assert "[objects." in scenario and "[events." in scenario
    assert any("optimize" in block for block, _ in commands)
    assert any("template" in block and shown for block, shown in commands)
    assert normalised("outcome: success (2/2 events, 0.364 s simulated in 0.02 s)") == \
        "outcome: success (2/2 events, 0.364 s simulated in T s)"


def _toml_blocks():
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        for k, (lang, body) in enumerate(BLOCK.findall(page.read_text())):
            if lang == "toml":
                yield pytest.param(body, id=f"{page.relative_to(ROOT)}:{k}")


@pytest.mark.parametrize("body", list(_toml_blocks()))
def test_every_toml_snippet_in_the_docs_loads(body, tmp_path):
    # a whole scenario loads as `rgmcad check` reads it; a fragment, or an illustration of
    # every key with "..." for names, is TOML of the tables a scenario has
    import tomllib

    from rgmcad.scene.loader import load_scenario

    data = tomllib.loads(body)
    if "objects" in data and '"..."' not in body:  # "...": a key-by-key illustration
        path = tmp_path / "snippet.toml"
        path.write_text(body)
        assert load_scenario(path).objects
    else:
        assert set(data) <= {"name", "description", "objects", "events", "runs", "ropes",
                             "joints", "layouts", "simulation"}, data
