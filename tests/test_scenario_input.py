"""Scenario files as hostile or careless input: the loader returns a Scenario whose numbers are
all finite, or raises one ScenarioError line naming the file and the key; never anything else.

Three laws over generated documents (any TOML-like document, mutations of the shipped
scenarios' data, and mutations of their text), then a corpus of hand-written bad scenarios
(tests/data/bad_scenarios/, each naming the key its error must name) run through the CLI.
"""

from __future__ import annotations

import copy
import dataclasses
import datetime
import enum
import json
import logging
import math
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rgmcad.cli import main
from rgmcad.errors import ScenarioError
from rgmcad.scene import schema
from rgmcad.scene.eventspec import EVENT_TYPES
from rgmcad.scene.loader import TOP_KEYS, load_scenario, parse_scenario
from rgmcad.scene.model import SIMULATION_KEYS, Scenario

SCENARIOS = sorted(Path("scenarios").glob("*.toml"))
SHIPPED = {p.stem: tomllib.loads(p.read_text()) for p in SCENARIOS}
BAD = Path(__file__).parent / "data" / "bad_scenarios"
EXAMPLES = int(os.environ.get("RGMCAD_FUZZ_EXAMPLES", "400"))
"""Examples per law; a longer campaign (random, not the fixed examples of the suite):
``RGMCAD_FUZZ_EXAMPLES=20000 uv run pytest tests/test_scenario_input.py -k load``."""
FUZZ = settings(max_examples=EXAMPLES, deadline=None, derandomize="RGMCAD_FUZZ_EXAMPLES" not in os.environ,
                database=None, suppress_health_check=list(HealthCheck))


# --- the law ----------------------------------------------------------------------------------


def _numbers(value, seen=None):
    """Every number held in a scenario (its families' code excluded)."""
    if isinstance(value, bool | enum.Enum | str | Path) or value is None:
        return
    if isinstance(value, int | float | np.number):
        yield value
    elif isinstance(value, np.ndarray):
        yield from value.ravel().tolist()
    elif isinstance(value, dict):
        for v in value.values():
            yield from _numbers(v)
    elif isinstance(value, list | tuple):
        for v in value:
            yield from _numbers(v)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            if f.name != "families":
                yield from _numbers(getattr(value, f.name))


def _law(load):
    """``load()`` gives a Scenario of finite numbers, or one ScenarioError line."""
    try:
        scenario = load()
    except ScenarioError as exc:
        assert len(str(exc).splitlines()) == 1, str(exc)
        assert len(str(exc)) < 2000
        return None
    assert isinstance(scenario, Scenario)
    bad = [v for v in _numbers(scenario) if not math.isfinite(v)]
    assert not bad, bad
    assert len(scenario.objects) <= schema.MAX_BODIES
    return scenario


# --- documents --------------------------------------------------------------------------------

NASTY = [math.nan, math.inf, -math.inf, -1, -1.0, 0, 0.0, -0.0, 1e308, -1e308, 10**30, 2**63,
         5e-324, 1e-9, 1e6, 100_000, "", "x", "a\nb", "../../x", "/abs", [], [[]], [0, 0, 0],
         [math.nan, 1, 2], {}, {"x": math.nan}, True, False, datetime.date(2020, 1, 1),
         datetime.time(1, 2), [1, "a"], [[1], "b"]]
SCALARS = (st.booleans() | st.integers(-2**70, 2**70) | st.floats() | st.text(max_size=8)
           | st.dates() | st.times() | st.sampled_from(NASTY))
VALUES = st.recursive(SCALARS, lambda inner: st.lists(inner, max_size=4)
                      | st.dictionaries(st.text(max_size=6), inner, max_size=4), max_leaves=12)
KEYS = sorted({*TOP_KEYS, "parts", *SIMULATION_KEYS, *schema.PHYSICAL, *schema.POSE, "part",
               "params", "parent", "free", "domino", "path", "tilt", "kind", "count", "spacing",
               "points", "type", "after", "hold", "timeout", "negate", "join", "point", "end",
               "axis", "objects", "radius", "length", "width", "height", "wall", "sectors",
               *schema.EVENT_PARAMS, *schema.DOMINO, *(k for t in schema.PATHS.values() for k in t)})


@FUZZ
@given(st.dictionaries(st.sampled_from(KEYS) | st.text(max_size=6), VALUES, max_size=6))
def test_any_document_loads_or_gives_one_error_line(doc):
    _law(lambda: parse_scenario(doc, where="<fuzz>"))


def _paths(node, here=()):
    """Every path (tuple of keys and indices) into a document, the root excluded."""
    items = node.items() if isinstance(node, dict) else \
        enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield (*here, k)
        yield from _paths(v, (*here, k))


def _at(doc, path):
    for k in path:
        doc = doc[k]
    return doc


@st.composite
def mutated(draw):
    """A shipped scenario's data with 1-3 values replaced, keys deleted or keys added."""
    def fresh(strategy):  # NASTY's lists and tables are shared: never mutate them
        return copy.deepcopy(draw(strategy))

    doc = copy.deepcopy(SHIPPED[draw(st.sampled_from(sorted(SHIPPED)))])
    for _ in range(draw(st.integers(1, 3))):
        paths = list(_paths(doc))
        path = draw(st.sampled_from(paths))
        parent, last = _at(doc, path[:-1]), path[-1]
        action = draw(st.sampled_from(["replace", "replace", "nasty", "delete", "add"]))
        if action == "delete":
            del parent[last]
        elif action == "add":
            target = _at(doc, path)
            if isinstance(target, dict):
                target[draw(st.sampled_from(KEYS) | st.text(max_size=4))] = fresh(VALUES)
            elif isinstance(target, list):
                target.append(fresh(VALUES))
        else:
            parent[last] = fresh(st.sampled_from(NASTY) if action == "nasty" else VALUES)
    return doc


@FUZZ
@given(mutated())
def test_mutated_shipped_scenarios_load_or_give_one_error_line(doc):
    _law(lambda: parse_scenario(doc, where="<mutated>"))


TOKENS = st.sampled_from(["nan", "inf", "-inf", "-1", "0", "1e999", "true", "[", "]", "{", "}",
                          "=", '"', ",", "\n", "[[joints]]", "[objects.x]", "1e-320", "0x10",
                          "99999999999999999999999", "\xe9", "\\", "'", ".", "#"])


@FUZZ
@given(st.sampled_from(SCENARIOS), st.data())
def test_mutated_shipped_texts_load_or_give_one_error_line(tmp_path_factory, path, data):
    text = path.read_text()
    for _ in range(data.draw(st.integers(1, 3))):
        start = data.draw(st.integers(0, len(text)))
        end = data.draw(st.integers(start, min(len(text), start + 12)))
        text = text[:start] + "".join(data.draw(st.lists(TOKENS, max_size=3))) + text[end:]
    file = tmp_path_factory.mktemp("fuzz") / "mutated.toml"
    file.write_text(text)
    _law(lambda: load_scenario(file))


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_shipped_scenarios_obey_the_law_and_warn_of_nothing(path, caplog):
    with caplog.at_level(logging.WARNING):
        assert _law(lambda: load_scenario(path)) is not None
    assert not caplog.records


# --- the table --------------------------------------------------------------------------------


def _specs():
    tables = [schema.SIMULATION, schema.PHYSICAL, schema.POSE, schema.RUN, schema.DOMINO,
              schema.EVENT_PARAMS, schema.EVENT, schema.POINT, schema.JOINT, schema.ROPE,
              *schema.PATHS.values()]
    for table in tables:
        for spec in table.values():
            while not isinstance(spec, schema.Number | schema.Flag | schema.Text):
                spec = spec.point if isinstance(spec, schema.Points) else spec.number
            yield spec


def test_the_table_covers_every_key_and_bounds_every_number():
    assert list(schema.SIMULATION) == list(SIMULATION_KEYS)
    assert {p for t in EVENT_TYPES.values() for p in t.params} <= set(schema.EVENT_PARAMS)
    from rgmcad.scene.loader import PATH_MAKERS

    assert set(PATH_MAKERS) == set(schema.PATHS)
    for kind, make in PATH_MAKERS.items():
        import inspect

        assert set(inspect.signature(make).parameters) == set(schema.PATHS[kind])
    for spec in _specs():
        if isinstance(spec, schema.Number):
            assert math.isfinite(spec.low) and math.isfinite(spec.high) and spec.low < spec.high


def test_the_reference_page_shows_the_table():
    # the generated Scenario files page (docs/hooks.py) carries the table, cells made HTML-safe
    from rgmcad.reference import scenario as scenario_page

    assert scenario_page._html_safe(schema.markdown()) in scenario_page.page()


# --- warnings of likely slips of units -------------------------------------------------------

SIMPLE = Path("scenarios/simple.toml").read_text()


@pytest.mark.parametrize("old, new, key, slip", [
    ("radius = 0.01", "radius = 10", "objects.ball.params.radius", "millimetres"),
    ("mass = 0.03", "mass = 50", "runs.run.mass", "grams"),
    ("thickness = 0.005", "thickness = 5", "runs.run.domino.thickness", "millimetres"),
    ("mass = 0.01", "density = 7.8", "objects.ball.density", "grams per cm^3"),
    ("roll = [15, 75]", "roll = [0.26, 1.31]", "objects.track.free.roll", "radians"),
    ("pose = { x = -0.02, z = 0.01 }", "pose = { x = -20, z = 0.01 }", "objects.ball.pose.x",
     "millimetres"),
])
def test_implausible_sizes_and_masses_warn_naming_the_key(old, new, key, slip, tmp_path, caplog):
    file = tmp_path / "slip.toml"
    file.write_text(SIMPLE.replace(old, new, 1))
    with caplog.at_level(logging.WARNING, logger="rgmcad"):
        load_scenario(file)
    messages = [r.getMessage() for r in caplog.records]
    assert len(messages) == 1 and key in messages[0] and slip in messages[0], messages


def test_a_refused_file_gives_no_warning(tmp_path, caplog):
    file = tmp_path / "slip.toml"
    file.write_text(SIMPLE.replace("mass = 0.03", "mass = 50").replace("duration = 3.0",
                                                                         "duration = -3.0"))
    with caplog.at_level(logging.WARNING), pytest.raises(ScenarioError, match="duration"):
        load_scenario(file)
    assert not caplog.records


# --- part families come from the command line, never the file --------------------------------


def test_a_scenario_cannot_name_a_parts_folder(tmp_path):
    (tmp_path / "evil").mkdir()
    (tmp_path / "evil" / "boom.py").write_text("raise SystemExit('ran code from a scenario')\n")
    file = tmp_path / "s.toml"
    file.write_text('parts = "evil"\n' + SIMPLE)
    with pytest.raises(ScenarioError, match="--parts DIR"):
        load_scenario(file)


def test_parts_option_loads_families_from_a_folder(tmp_path, capsys):
    parts = tmp_path / "parts"
    parts.mkdir()
    for p in Path("parts").glob("*.py"):
        (parts / p.name).write_text(p.read_text())
    (parts / "ball.py").write_text((parts / "ball.py").read_text()
                                   .replace('name="ball"', 'name="marble"'))
    file = tmp_path / "s.toml"
    file.write_text(SIMPLE.replace('part = "ball"', 'part = "marble"'))
    args = ["--parts", str(parts), "check", str(file)]
    assert main(args[:2] + ["check", "scenarios/simple.toml"]) == 2  # no ball in that folder
    assert "unknown part 'ball'" in capsys.readouterr().err
    assert main(args) == 0
    assert "marble" in capsys.readouterr().out
    assert main(["--parts", str(tmp_path / "nowhere"), "check", str(file)]) == 2
    assert "--parts" in capsys.readouterr().err
    # the commands that simulate many layouts use them too, in their worker processes
    plot = tmp_path / "curve.png"
    assert main([*args[:2], "evaluate", str(file), "--layout", "initial", "--rho-g", "--samples", "1",
                 "--workers", "1", "--out", str(plot), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["simulations"] > 0 and plot.is_file()
    assert main([*args[:2], "build", "parts", str(file), "--out", str(tmp_path / "b")]) == 0
    assert "marble" in (tmp_path / "b" / "manifest.json").read_text()


# --- the corpus of bad scenarios, through the CLI ---------------------------------------------


def _expected(path: Path) -> tuple[str, str]:
    """(key, words of the message) from a corpus file's ``# key:`` and ``# says:`` lines."""
    head = path.read_bytes()[:400].decode("utf-8", "replace").splitlines()
    fields = dict(line[2:].partition(":")[::2] for line in head if line.startswith("# "))
    return fields.get("key", "").strip(), fields.get("says", "").strip()


CORPUS = sorted(p for p in BAD.iterdir() if p.suffix in (".toml", ".bin"))


def test_the_corpus_is_there():
    assert len(CORPUS) >= 60
    assert all(_expected(p) != ("", "") for p in CORPUS), "each file says what it expects"


@pytest.mark.parametrize("path", CORPUS, ids=lambda p: p.stem)
def test_bad_scenario_gives_one_line_naming_the_key(path, capsys):
    key, says = _expected(path)
    assert main(["check", str(path)]) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1, err
    prefix = f"rgmcad: error: {path}: " + (f"{key}: " if key else "")
    assert err.startswith(prefix), (prefix, err)
    assert says in err, (says, err)


def test_missing_file_and_folder_give_one_line(tmp_path, capsys):
    for target in (tmp_path / "missing.toml", tmp_path):
        assert main(["check", str(target)]) == 2
        assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_corpus_from_a_separate_process_exits_2_without_traceback():
    picks = [BAD / "deep_arrays.toml", BAD / "not_utf8.bin", BAD / "run_of_100000.toml",
             BAD / "mass_nan.toml"]
    for path in picks:
        done = subprocess.run([sys.executable, "-m", "rgmcad.cli", "check", str(path)],
                              capture_output=True, text=True, timeout=60)
        assert done.returncode == 2, done.stderr
        assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
