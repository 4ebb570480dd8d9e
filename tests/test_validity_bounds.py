"""The validity test's work is bounded before it starts: two domino runs that are each fine
but cross each other make up to a million overlapping pairs (two runs of 1,000 wide dominoes
crossing), and ``rgmcad check``, ``rgmcad simulate`` and the samplers' vectorised test answer
within seconds, naming the deepest few pairs and how many more there are. Ordinary scenarios
keep every penetration and every verdict. The time bound is a guard against hangs, not a
benchmark."""

from __future__ import annotations

import time

import numpy as np
import pytest
from _support import cli_output

import rgmcad.sim.validity as validity_module
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import bounds, values_from_mapping
from rgmcad.scene.loader import load_scenario
from rgmcad.shipped import shipped_scenarios
from rgmcad.sim.layout_validity import MAX_VECTOR_PAIRS, LayoutValidity
from rgmcad.sim.validity import ENOUGH_OVERLAPS, SHOWN, Overlap, Validity, check_validity

HANG = 5.0  # s: a verdict later than this is a hang


def crossing(n: int, width: float, angle: float, spacing: float, thickness: float) -> str:
    """Two runs of ``n`` dominoes (``thickness`` by ``width``, ``spacing`` apart) crossing
    at their middles at ``angle`` degrees: each run alone is fine."""
    length = (n - 1) * spacing
    run = (f'domino = {{ thickness = {thickness}, width = {width}, height = 0.04 }}\n'
           f'mass = 0.003\n')
    return f'''name = "crossing"
[simulation]
duration = 1.0
[objects.floor]
part = "plane"
[runs.a]
{run}path = {{ kind = "line", count = {n}, length = {length}, origin = [{-length / 2}, 0] }}
[runs.b]
{run}path = {{ kind = "line", count = {n}, length = {length}, origin = [{-length / 2}, 0] }}
pose = {{ heading = {angle} }}
[events.e]
type = "toppling"
body = "a[0]"
angle = 45
'''


CROSSINGS = {  # pairs whose boxes overlap: 90,000, about a million, a few hundred, 8,100
    "300 wide plates square": (300, 0.9, 90, 0.003, 0.002),
    "998 wide plates square": (998, 1.99, 90, 0.002, 0.0015),
    "998 dominoes at 2 degrees": (998, 0.02, 2, 0.005, 0.002),
    "90 wide plates square": (90, 0.27, 90, 0.003, 0.002),
}


@pytest.fixture(scope="module", params=list(CROSSINGS))
def crossed(request, tmp_path_factory):
    """A crossing scenario file, its parts built (CadQuery's time is not the test's)."""
    path = tmp_path_factory.mktemp("crossing") / "crossing.toml"
    path.write_text(crossing(*CROSSINGS[request.param]))
    scenario = load_scenario(path)
    return path, scenario, load_parts(scenario), request.param


def timed(f, *args):
    start = time.perf_counter()
    out = f(*args)
    return out, time.perf_counter() - start


def test_rgmcad_check_gives_its_verdict_on_crossing_runs_at_once_naming_a_few_pairs(crossed):
    path = crossed[0]
    (code, out, err), took = timed(cli_output, ["check", str(path)])
    assert code == 1 and "Traceback" not in err, err[-600:]
    (line,) = [li for li in out.splitlines() if li.startswith("  initial:")]
    assert "INVALID" in line and line.count(" mm; ") == SHOWN and "more pairs" in line, line
    assert len(line) < 600 and took < HANG, (took, line[:600])


def test_rgmcad_simulate_refuses_crossing_runs_at_once_in_a_few_lines(crossed):
    path = crossed[0]
    (code, out, err), took = timed(cli_output, ["simulate", str(path)])
    assert code == 1 and "outcome: invalid" in out and "Traceback" not in err, (out + err)[-600:]
    assert sum(" overlap by " in li for li in out.splitlines()) == SHOWN, out[-600:]
    assert len(out.splitlines()) <= SHOWN + 3 and took < HANG, (took, out[-600:])


def test_the_validity_test_stops_once_enough_pairs_overlap(crossed):
    _, scenario, parts, case = crossed
    scene = make_scene(scenario, values_from_mapping(scenario, {}), parts)
    result, took = timed(check_validity, scene)
    assert not result.valid and took < HANG
    if "square" in case:
        n = CROSSINGS[case][0]
        assert len(result.overlaps) == ENOUGH_OVERLAPS and result.untested > 0.9 * n * n
        assert "were not tested" in result.shown()[1]


def test_the_samplers_test_of_crossing_runs_is_bounded_and_agrees(crossed):
    _, scenario, parts, _ = crossed
    low, high = bounds(scenario)
    tester, took = timed(LayoutValidity, scenario, parts)
    answer, took_call = timed(tester, np.atleast_2d((low + high) / 2))
    assert answer.tolist() == [False] and took + took_call < HANG
    solids = len(tester.solids)
    assert tester.one_by_one == (solids * (solids - 1) // 2 > MAX_VECTOR_PAIRS)


# --- ordinary scenarios: every penetration listed, every verdict unchanged ----------------

@pytest.mark.parametrize("name", ["causality_switch", "long_chain"])
def test_ordinary_scenarios_keep_every_overlap_and_every_verdict(name, monkeypatch):
    """The bound never reaches a shipped scenario's layouts (named and random ones), and
    with it forced on (a limit of 0 pairs) each verdict is the same."""
    scenario = load_scenario(shipped_scenarios()[name])
    parts = load_parts(scenario)
    low, high = bounds(scenario)
    rng = np.random.default_rng(3)
    rows = [values_from_mapping(scenario, m) for m in scenario.layouts.values()]
    rows += list(low + rng.random((12, len(low))) * (high - low))
    full = [check_validity(make_scene(scenario, v, parts)) for v in rows]
    assert all(r.untested == 0 for r in full)
    assert full[list(scenario.layouts).index("solved")].valid
    assert {r.valid for r in full} == {True, False}  # both verdicts are exercised
    monkeypatch.setattr(validity_module, "MAX_EXACT_PAIRS", 0)
    monkeypatch.setattr(validity_module, "ENOUGH_OVERLAPS", 1)
    bounded = [check_validity(make_scene(scenario, v, parts)) for v in rows]
    assert [r.valid for r in bounded] == [r.valid for r in full]
    assert [r.valid for r in full] == LayoutValidity(scenario, parts)(np.array(rows)).tolist()


def test_a_report_lists_every_overlap_up_to_five_then_the_deepest_five():
    few = Validity(False, tuple(Overlap(f"a{k}", "b", k * 1e-3, 0.0) for k in range(5)), 5)
    assert few.shown() == (few.overlaps, None)
    many = Validity(False, tuple(Overlap(f"a{k}", "b", k * 1e-3, 0.0) for k in range(8)), 8)
    shown, more = many.shown()
    assert [o.first for o in shown] == ["a7", "a6", "a5", "a4", "a3"]
    assert more == "and 3 more pairs overlap"
    cut = Validity(False, many.overlaps, 8, untested=12345)
    assert cut.shown()[1] == ("and 3 more pairs overlap; 12,345 more pairs whose boxes overlap "
                              "were not tested")
