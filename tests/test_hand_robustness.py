"""How often a layout works when a person builds it (rgmcad.runs.hand): the headline a maker
reads, in millimetres and degrees, by simulation; sequential, on common draws; the same
whatever the ranges typed in the file; its weak links the parts that break the machine."""

import json
import re
from pathlib import Path

import numpy as np
import pypdfium2 as pdfium
import pytest

from rgmcad.runs.hand import (
    Hand,
    HandSettings,
    careful_hands,
    hand_race,
    measure_rate,
    parse_hand,
    weak_links,
)
from rgmcad.runs.problem import ScenarioProblem, SimRecord
from rgmcad.scene.design_space import vector_from_values
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges, placement_groups
from rgmcad.sim.run import Outcome
from tests._support import cli_output

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = str(ROOT / "scenarios" / "simple.toml")
BALLRUN = str(ROOT / "scenarios" / "ballrun.toml")


def _record(success: bool) -> SimRecord:
    return SimRecord(True, Outcome.SUCCESS if success else Outcome.FAILURE,
                     {"e": (success, 0.1)}, 0.0)


class _Coin:
    """A fake ``simulate``: draw ``k`` succeeds where ``works(k, moved)``; remembers draws."""

    def __init__(self, works):
        self.works, self.draws = works, []

    def __call__(self, draws):
        self.draws += draws
        return [_record(self.works(d.index, d.moved)) for d in draws]


def test_the_rate_stops_as_soon_as_its_interval_is_narrow_enough():
    always = _Coin(lambda k, moved: True)
    rate = measure_rate(always, Hand(), None, 0, precision=0.05, batch=32, minimum=64)
    assert (rate.samples, rate.successes) == (64, 64)  # [0.94, 1]: narrow at the minimum
    assert (rate.high - rate.low) / 2 <= 0.05
    assert [d.index for d in always.draws] == list(range(64))  # draws 0, 1, ...: common
    half = _Coin(lambda k, moved: k % 2 == 0)
    rate = measure_rate(half, Hand(), None, 0, precision=0.05, batch=32, maximum=320)
    assert rate.samples == 320 and rate.rate == 0.5  # never that narrow: the most allowed
    assert rate.low < 0.5 < rate.high
    mostly = _Coin(lambda k, moved: k % 10 != 0)
    rate = measure_rate(mostly, Hand(), None, 0, precision=0.05, batch=32, maximum=320)
    assert rate.samples < 320 and (rate.high - rate.low) / 2 <= 0.05
    assert measure_rate(_Coin(lambda k, m: k % 10 != 0), Hand(), None, 0) == rate


def test_weak_links_draw_more_only_for_the_parts_that_failed():
    groups = {"sturdy": ["a"], "fragile": ["b"], "run": ["c1", "c2"]}
    coin = _Coin(lambda k, moved: not ("b" in moved and k % 2) and not ("c1" in moved and k == 5))
    links = weak_links(coin, groups, Hand(), 0, first=8, most=32)
    by_name = {w.name: w for w in links}
    assert [w.name for w in links] == ["fragile", "run", "sturdy"]
    assert by_name["sturdy"].rate.samples == 8  # never failed: no more draws
    assert by_name["fragile"].rate.samples == by_name["run"].rate.samples == 32
    assert by_name["fragile"].rate.successes == 16 and by_name["run"].rate.successes == 31
    assert by_name["run"].objects == ("c1", "c2")
    assert {d.moved for d in coin.draws} == {frozenset(g) for g in groups.values()}
    assert all(d.ranges.friction == d.ranges.mass == 0 for d in coin.draws)  # physics as is


def test_the_final_choice_by_hand_keeps_the_best_and_stops_when_all_are_as_good():
    rates = {0: 0.7, 1: 0.9, 2: 0.2}  # candidate i works on draw k where (k * 7919) % 100 <
    met = {i: [] for i in rates}

    def simulate_at(i, draws):
        met[i] += [d.index for d in draws]
        return [_record((d.index * 7919) % 100 < 100 * rates[i]) for d in draws]

    winner, got = hand_race(simulate_at, 3, Hand(), None, 0, first=32, most=320)
    assert winner == 1 and got[1].samples >= got[0].samples
    assert got[2].samples == 32  # dropped at the first stage: clearly worse
    assert all(m == list(range(len(m))) for m in met.values())  # the same builds for all
    same = {i: [] for i in range(3)}
    winner, got = hand_race(lambda i, draws: same[i].extend(draws) or [_record(True)] * len(
        draws), 3, Hand(), None, 0, first=32, most=320)
    assert winner == 0 and [r.samples for r in got] == [32, 32, 32]  # equal: no more builds


def test_a_weak_link_gets_the_hand_it_needs_by_simulation():
    # the track works misplaced alone within 1 mm, not 1.5; the ball never fails
    def simulate(draws):
        return [_record("track" not in d.moved or (d.ranges.position <= 0.001 + 1e-12
                                                   or d.index % 2 == 0)) for d in draws]

    links = weak_links(simulate, {"track": ["track"], "ball": ["ball"]}, Hand(), 0)
    links = careful_hands(simulate, links, Hand(), 0, samples=16)
    track = links[0].to_json()
    assert track["name"] == "track" and track["successes"] < track["samples"]
    assert (track["careful"]["position_mm"], track["careful"]["heading_deg"]) == (1.0, 1.0)
    assert track["careful"]["successes"] == track["careful"]["samples"] == 16
    assert links[1].careful is None  # never failed: needs no care


def test_a_part_misplaced_alone_is_where_the_full_draw_put_it():
    ranges = PhysicsRanges(position=0.002, heading=2.0)
    full = PhysicsDraw(ranges, 3, 7).offsets(["a", "b", "c"])
    alone = PhysicsDraw(ranges, 3, 7, frozenset({"b"})).offsets(["a", "b", "c"])
    assert set(alone) == {"b"} and np.array_equal(alone["b"], full["b"])
    assert all(abs(o[0]) <= 0.002 and abs(o[1]) <= 0.002 and abs(o[3]) <= 2.0
               for o in full.values())


@pytest.mark.parametrize("text, key", [("2", "'2'"), ("2mm,x", "'x'"), ("-1mm", "mm"),
                                       ("99deg", "deg"), ("nanmm", "mm")])
def test_a_hand_is_read_in_millimetres_and_degrees(text, key):
    from rgmcad.errors import UsageError

    with pytest.raises(UsageError, match=re.escape(key)):
        parse_hand(text)
    assert parse_hand("3mm, 1.5deg") == Hand(3.0, 1.5) and parse_hand("1deg") == Hand(2.0, 1.0)


@pytest.mark.parametrize("extra, flag", [(["--hand", "2"], "--hand"),
                                         (["--precision", "0"], "--precision"),
                                         (["--samples", "5"], "--samples")])
def test_evaluate_refuses_a_bad_hand_in_one_line(extra, flag, tmp_path):
    code, out, err = cli_output(["evaluate", SIMPLE, "--layout", "solved", *extra,
                                 "--out", str(tmp_path / "h.png")])
    assert code == 2 and not out and len(err.strip().splitlines()) == 1 and flag in err
    assert not (tmp_path / "h.png").exists()


def test_a_layout_whose_parts_overlap_is_refused_in_one_line(tmp_path):
    layout = tmp_path / "sunk.json"
    layout.write_text(json.dumps({"scenario": "simple", "vector": [0.5, 0.0, 0.5]}))
    code, out, err = cli_output(["evaluate", SIMPLE, "--layout", str(layout), "--workers", "1"])
    assert code == 2 and len(err.strip().splitlines()) == 1 and "overlap" in err


def _evaluate(tmp_path, scenario, *extra):
    code, out, _ = cli_output(["evaluate", scenario, "--layout", "solved", "--workers", "1",
                               "--out", str(tmp_path / "h.png"), "--json", *extra])
    assert code == 0
    return json.loads(out)


def test_evaluate_states_how_often_a_built_layout_works(tmp_path):
    result = _evaluate(tmp_path, SIMPLE)
    head = result["hand"]
    assert (head["position_mm"], head["heading_deg"]) == (2.0, 2.0)
    assert head["physics"] == PhysicsRanges().to_json()  # physical errors on by default
    low, high = head["interval"]
    assert low <= head["rate"] <= high and head["rate"] == head["successes"] / head["samples"]
    assert (high - low) / 2 <= result["precision"] or head["samples"] == 320
    sizes = [c["position_mm"] for c in result["hand_curve"]]
    assert sizes == [0, 1, 2, 3, 5, 7, 10]
    assert [c["heading_deg"] for c in result["hand_curve"]] == sizes  # 1 degree per mm
    assert result["hand_curve"][2] == head  # the headline is the curve's point at 2 mm
    assert (tmp_path / "h.png").stat().st_size > 0
    names = {w["name"] for w in result["weak_links"]}
    assert names == {"ball", "track", "run"}  # the floor is an infinite plane: not placed
    code, out, err = cli_output(["evaluate", SIMPLE, "--layout", "solved", "--workers", "1",
                                 "--out", str(tmp_path / "h2.png"), "--hand", "4mm,1deg"])
    assert code == 0
    # progress: each stage counted against its total (at most so many builds), time left
    assert re.search(r"builds within \+-4 mm and \+-1 deg: +\d+%\|.*\| \d+/320 \[", err)
    assert re.search(r"success against hand error: +\d+%\|.*\| \d+/144 \[", err)
    # the headline as soon as it is known, before the stages that follow it
    early = err.index("the curve and the weak links follow")
    assert early < err.index("success against hand error") and "works " in err[:early]
    assert re.search(r"works \d+ % \[\d+, \d+\] of the time when each part is placed within "
                     r"\+-4 mm and \+-1 degrees", out)
    assert "+-10.0 mm, +- 2.5 deg" in out.replace("+-2.5", "+- 2.5")  # the hand's ratio kept


def test_a_range_typed_twice_as_wide_changes_rho_g_but_not_the_hand_figure(tmp_path):
    wide = tmp_path / "simple.toml"
    wide.write_text(Path(SIMPLE).read_text().replace("free = { x = [-0.15, 0.0],",
                                                     "free = { x = [-0.30, 0.0],"))
    def hand_rate(path):
        problem = ScenarioProblem(path)
        context = problem.context()
        x = vector_from_values(context.scenario, resolve_layout(context.scenario, "solved",
                                                                None)[1])
        return measure_rate(lambda draws: [context.simulate_one(x, True, d) for d in draws],
                            Hand(), PhysicsRanges(), 0, minimum=32, maximum=32), x

    (narrow_hand, narrow_x), (wide_hand, wide_x) = hand_rate(SIMPLE), hand_rate(str(wide))
    assert narrow_x[0] != wide_x[0]  # the same layout, another normalised coordinate
    assert narrow_hand == wide_hand  # the same builds: every part within 2 mm of its place
    narrow_rho, wide_rho = (_evaluate(tmp_path, s, "--rho-g", "--samples", "1")
                            for s in (SIMPLE, str(wide)))
    assert narrow_rho["curve"] != wide_rho["curve"]  # other neighbourhoods


def test_the_weak_link_named_is_the_part_that_breaks_the_machine():
    problem = ScenarioProblem(BALLRUN)
    context = problem.context()
    _, values = resolve_layout(context.scenario, "solved", None)
    x = vector_from_values(context.scenario, values)
    groups = placement_groups(context.scenario,
                              [n for n, p in context.parts.items() if p.infinite])
    links = weak_links(lambda draws: [context.simulate_one(x, True, d) for d in draws], groups,
                       Hand(), 0, first=4, most=8)
    weakest = links[0].to_json()
    assert weakest["successes"] < weakest["samples"]
    others = frozenset(o for name, g in groups.items() if name != weakest["name"] for o in g)
    ranges = Hand().ranges(None)
    n = 32

    def works(moved):
        return sum(context.simulate_one(x, True, PhysicsDraw(ranges, 0, k, moved)).outcome
                   is Outcome.SUCCESS for k in range(n)) / n

    # every other part misplaced, the weak link put exactly: it works clearly more often than
    # when only the weak link is misplaced
    assert works(others) >= weakest["successes"] / weakest["samples"] + 0.2


def test_optimize_states_the_hand_figure_in_its_summary_report_and_template(tmp_path):
    run = tmp_path / "run"
    code, out, _ = cli_output(["optimize", SIMPLE, "--budget", "small", "--run", str(run),
                               "--workers", "1"])
    assert code in (0, 1)
    summary = json.loads((run / "result.json").read_text())
    hand = summary["hand"]
    assert hand["hand"]["samples"] >= 16 and hand["seed"] == 0
    assert summary["simulations_by_stage"]["hand"] == hand["simulations"]
    builds = hand["simulations"] + summary["simulations_by_stage"].get("choice by hand", 0)
    assert "built by hand: works" in out and f"{builds} builds by hand" in out
    assert "## Built by hand" in (run / "report.md").read_text()
    assert (run / "hand.png").stat().st_size > 0
    assert "built by hand: <b>works" in (run / "report.html").read_text()
    note = json.loads((run / "layout.json").read_text())["built_by_hand"]
    code, out, _ = cli_output(["template", SIMPLE, "--layout", str(run / "layout.json"),
                               "--out", str(tmp_path / "t"), "--json"])
    assert code == 0 and json.loads(out)["built_by_hand"] == note
    cover = pdfium.PdfDocument(str(tmp_path / "t" / "template.pdf"))[0]
    text = cover.get_textpage().get_text_range()
    assert note.split(" (")[0] in " ".join(text.split())


class _FakeBuilds:
    """A fake :class:`~rgmcad.runs.hand.Builds`: build ``k`` of layout ``x`` works where
    ``works(x, k)``; counts the builds it simulates."""

    def __init__(self, works):
        self.works, self.simulations, self.seen = works, 0, []

    def __call__(self, x, draws):
        self.simulations += len(draws)
        self.seen.append([d.index for d in draws])
        return [_record(self.works(np.asarray(x), d.index)) for d in draws]


def test_a_printed_tolerance_is_pulled_in_until_it_works_as_often_under_the_hand():
    from rgmcad.runs.hand_bounds import hand_at_bounds
    from rgmcad.runs.tolerance_check import CheckedTolerances
    from rgmcad.scene.loader import load_scenario

    scenario = load_scenario(SIMPLE)  # track.x [-0.15, 0] m, track.z, track.roll (deg)
    width = np.array([0.15, *[f.high - f.low for f in scenario.free[1:]]])
    x = np.full(3, 0.5)

    def works(v, k):  # track.x beyond 5 mm from x: every other build fails; roll never
        off_mm = abs(v[0] - x[0]) * width[0] * 1000
        return off_mm <= 5.0 + 1e-9 or k % 2 == 0

    tol = np.array([[12e-3, 4e-3], [2e-3, 0.0], [3.0, 3.0]]) / width[:, None]
    checked = CheckedTolerances(tol, np.zeros((3, 2), bool), 10)
    skip = np.zeros((3, 2), bool)
    fake = _FakeBuilds(works)
    got = hand_at_bounds(checked, x, scenario, fake, Hand(), None, 0, 16, skip)
    printed = got.checked.tolerances * width[:, None]
    assert np.allclose(printed[0], [3e-3, 4e-3])  # 12 mm -> 6 (fails) -> 3 (holds); 4 holds
    assert got.narrowed[0, 0] and not got.narrowed[0, 1] and got.checked.narrowed[0, 0]
    assert np.allclose(printed[1:], [[2e-3, 0.0], [3.0, 3.0]])  # untouched, 0 not tried
    assert got.rates[0, 0] == (16, 16) and got.base == (16, 16)
    assert all(seen == list(range(16)) for seen in fake.seen)  # the headline's first builds
    assert got.simulations == fake.simulations == 16 * (1 + 5 + 2)  # layout, 5 sides, 2 more
    # a side that stops against a part is left as it is, failing or not
    skip[0, 0] = True
    kept = hand_at_bounds(checked, x, scenario, _FakeBuilds(works), Hand(), None, 0, 16, skip)
    assert np.allclose(kept.checked.tolerances[0, 0] * width[0], 12e-3)
    assert (0, 0) not in kept.rates
    # a side that fails at every halving is set to 0
    never = _FakeBuilds(lambda v, k: np.allclose(v, x) or k % 2 == 0)
    none = hand_at_bounds(checked, x, scenario, never, Hand(), None, 0, 16,
                          np.zeros((3, 2), bool))
    assert np.all(none.checked.tolerances[[0, 0, 2, 2], [0, 1, 0, 1]] == 0.0)
    assert none.to_json(scenario)["narrowed"] == {"track.x": "both", "track.z": "low",
                                                  "track.roll": "both"}


def test_at_each_printed_bound_a_layout_built_by_hand_works_as_often_on_new_builds():
    # as a maker does it: set the parameter at the printed bound, place the rest by hand,
    # and see it work as often as the layout does; judged on builds the check never saw
    from scipy.stats import binomtest

    from rgmcad.runs.executor import make_executor
    from rgmcad.runs.hand import Builds
    from rgmcad.runs.hand_bounds import hand_at_bounds
    from rgmcad.runs.tolerance_check import CheckedTolerances, printed_offsets
    from rgmcad.scene.design_space import bounds

    problem = ScenarioProblem(SIMPLE)
    scenario = problem.scenario
    samples = HandSettings().bound_samples  # as optimize checks them
    x = vector_from_values(scenario, resolve_layout(scenario, "solved", None)[1])
    width = np.subtract(*bounds(scenario)[::-1])
    model = np.array([[0.03, 0.03], [0.0, 0.0], [0.0, 0.0]]) / width[:, None]  # too generous
    executor = make_executor(1, problem.context)
    try:
        builds = Builds(executor)
        got = hand_at_bounds(CheckedTolerances(model, np.zeros((3, 2), bool), 0), x,
                             scenario, builds, Hand(), PhysicsRanges(), 0, samples,
                             np.zeros((3, 2), bool))
        # builds the check never saw (it may use twice its samples)
        fresh = [PhysicsDraw(Hand().ranges(PhysicsRanges()), 0, 2 * samples + i)
                 for i in range(48)]

        def worse_better(tolerances, side):
            moved = x.copy()
            offset = printed_offsets(tolerances, scenario)[side]
            moved[side[0]] += (offset if side[1] else -offset) / width[side[0]]
            base, at = ([r.outcome is Outcome.SUCCESS for r in builds(v, fresh)]
                        for v in (x, moved))
            return (sum(b and not a for b, a in zip(base, at, strict=True)),
                    sum(a and not b for b, a in zip(base, at, strict=True)))

        assert got.narrowed[0].any()
        for side in ((0, 0), (0, 1)):
            worse, better = worse_better(got.checked.tolerances, side)
            assert worse == 0 or binomtest(worse, worse + better,
                                           alternative="greater").pvalue >= 0.05, side
        # the model's 30 mm was no promise: at that bound the new builds fail more often
        assert any(binomtest(w, w + b, alternative="greater").pvalue < 0.05 for w, b in (
            worse_better(model, side) for side in ((0, 0), (0, 1))) if w)
    finally:
        executor.close()
