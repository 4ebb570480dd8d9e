"""Every tolerance ``optimize`` prints holds: a maker moves one parameter by the number on the
screen and the layout still works in simulation. The law of the check itself on a problem with
a known answer."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest

from rgmcad.runs.tolerance_check import check_tolerances
from tests._support import cli_output


def test_a_side_the_model_got_wrong_is_narrowed_to_where_it_still_succeeds():
    # success exactly where |x0 - 0.5| <= 0.1 and x1 <= 0.7: the model claims 0.3 on every
    # side; printed to 0.001 here (the step)
    def succeeds(P):
        return (np.abs(P[:, 0] - 0.5) <= 0.1 + 1e-12) & (P[:, 1] <= 0.7 + 1e-12)

    x = np.array([0.5, 0.5])
    calls = []
    got = check_tolerances(x, np.full((2, 2), 0.3),
                           lambda P: calls.append(len(P)) or succeeds(P), step=0.001)
    t = got.tolerances
    assert got.narrowed.tolist() == [[True, True], [False, True]]
    assert t[1, 0] == pytest.approx(0.3)  # simulated at every place, kept
    for (j, k), edge in (((0, 0), 0.1), ((0, 1), 0.1), ((1, 1), 0.2)):
        # narrowed: a whole number of steps, succeeding at the bound, within 1/64 of 0.3
        assert t[j, k] / 0.001 == pytest.approx(round(t[j, k] / 0.001))
        p = x.copy()
        p[j] += t[j, k] if k else -t[j, k]
        assert succeeds(p[None])[0]
        assert edge - 0.3 / 64 <= t[j, k] <= edge + 1e-12, (j, k, t[j, k])
    assert got.simulations == sum(calls) == 4 * 4 + 3 * 4 + 4 * 2  # and 2 a hair from each


def test_a_bound_a_hair_from_a_failure_steps_in_until_both_hairs_succeed():
    def succeeds(P):  # fails only in a band 0.05 to 0.15 steps beyond the model's bound
        return ~((P[:, 0] > 0.80005) & (P[:, 0] < 0.80015))

    got = check_tolerances(np.array([0.5]), np.array([[0.2, 0.3]]), succeeds, step=0.001)
    assert got.tolerances[0].tolist() == pytest.approx([0.2, 0.299])
    assert got.narrowed.tolist() == [[False, True]]
    assert got.simulations == 8 + 4 + 3  # places, hairs of both bounds, the step in


def test_no_side_is_checked_where_there_is_no_room():
    got = check_tolerances(np.array([0.0, 1.0]), np.zeros((2, 2)), lambda P: pytest.fail("ran"),
                           step=0.01)
    assert got.simulations == 0 and not got.narrowed.any()


_LINE = re.compile(r"^\s+(\S+)\s+(-?[\d.]+) (mm|deg)\s+(-[\d.]+|push against)[^/]*/ "
                   r"(\+[\d.]+|push against)")


def test_every_printed_tolerance_holds_at_its_bound_in_simulation(tmp_path):
    run = tmp_path / "run"
    code, out, err = cli_output(["optimize", "simple", "--budget", "small", "--run", str(run),
                                 "--workers", "1", "-q"])
    assert code == 0, err
    rows = [m.groups() for ln in out.splitlines() if (m := _LINE.match(ln))]
    summary = json.loads((run / "result.json").read_text())
    assert {r[0] for r in rows} == set(summary["values"]) and summary["tolerance_check"]
    layout = str(run / "layout.json")
    for name, _, unit, down, up in rows:
        k = 1000.0 if unit == "mm" else 1.0
        pushed = [t * k for t in summary["tolerances"][name]]  # to where the parts just clear
        for moved in (-pushed[0] if down == "push against" else float(down),
                      pushed[1] if up == "push against" else float(up)):
            if moved == 0:
                continue
            to = summary["values"][name] + moved / k  # the layout's value, moved as printed
            code, said, _ = cli_output(["-q", "simulate", "simple", "--layout", layout,
                                        "--value", f"{name}={to!r}"])
            assert code == 0 and "outcome: success" in said, (name, moved, said)


def test_a_side_that_stops_against_a_part_names_that_part():
    from rgmcad.runs.problem import ScenarioContext
    from rgmcad.runs.tolerance_check import pushed_against

    context = ScenarioContext.load("scenarios/simple.toml")
    try:
        low, high = 0.0, 0.5  # track.z: sunk into the floor at 0, standing at 0.5
        assert not context.validity(np.array([[0.5, low, 0.5]]))[0]
        while high - low > 1e-4:
            mid = (low + high) / 2
            low, high = (low, mid) if context.validity(np.array([[0.5, mid, 0.5]]))[0] \
                else (mid, high)
        x = np.array([0.5, high + 0.01, 0.5])  # 1 % of the range above touching the floor
        tol = np.full((3, 2), 0.005)
        tol[1, 0] = 0.01
        flags = np.zeros((3, 2), bool)
        flags[1] = True  # asked about both sides of track.z: only the lower meets a part
        got = pushed_against(context, x, tol, flags, past=0.002)
        assert got == {"track.z": {"low": "floor"}}
    finally:
        context.close()


def test_a_side_against_a_part_is_printed_as_a_push():
    from rgmcad.runs.report import placement_lines

    s = {"tolerances": {"track.z": [0.001, 0.0123]}, "values": {"track.z": 0.05},
         "overlap_ends": {"track.z": "low"}, "push_against": {"track.z": {"low": "floor"}},
         "tolerance_check": {"points_per_side": 4, "halvings": 4, "simulations": 8,
                             "narrowed": {}, "model_tolerances": {}},
         "verified": True, "probability": 0.9}
    line = next(line for line in placement_lines(s) if "track.z" in line)
    assert line.endswith("push against the floor / +12.3")


def test_the_template_says_push_where_the_layout_file_does(tmp_path):
    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({
        "scenario": "simple", "vector": [0.5, 0.5, 0.5],
        "tolerances": {"track.z": [0.001, 0.0123], "track.x": [0.002, 0.002]},
        "push_against": {"track.z": {"low": "floor"}, "track.x": {"high": "nowhere"}}}))
    code, out, _ = cli_output(["template", "scenarios/simple.toml", "--layout", str(layout),
                               "--out", str(tmp_path / "t"), "--json"])
    assert code == 0
    notes = next(p["notes"] for p in json.loads(out)["parts"] if p["name"] == "track")
    assert "z +12.3 mm; below: push against the floor" in notes
    assert "x ± 2 mm" in notes  # a part the scenario lacks: a plain tolerance


def test_each_side_is_confirmed_as_a_maker_sets_it_with_real_values():
    from rgmcad.runs.tolerance_check import CheckedTolerances, confirm_as_printed
    from rgmcad.scene.loader import load_scenario

    scenario = load_scenario("scenarios/simple.toml")  # track.x in [-0.15, 0], x, z, roll
    x = np.array([0.5, 0.5, 0.5])
    values = np.array([-0.075, 0.075, 45.0])
    asked = []

    def simulate_values(V):  # track.x works down to 29.95 mm below, roll to 5.97 deg above
        asked.append(V.copy())
        return (V[:, 0] >= values[0] - 0.02995) & (V[:, 2] <= values[2] + 5.97)

    checked = CheckedTolerances(np.array([[0.2, 0.1], [0.0, 0.3], [0.1, 0.1]]),
                                np.zeros((3, 2), bool), 10)
    got = confirm_as_printed(checked, x, scenario, simulate_values)
    width = np.array([0.15, 0.15, 60.0])
    real = got.tolerances * width[:, None]
    assert real[0, 0] == pytest.approx(0.0299) and real[2, 1] == pytest.approx(5.9)
    assert real[0, 1] == pytest.approx(0.015) and real[2, 0] == pytest.approx(6.0)
    assert real[1, 0] == 0.0 and real[1, 1] == pytest.approx(0.045)
    assert got.narrowed.tolist() == [[True, False], [False, False], [False, True]]
    # the layouts simulated are the real values moved by the printed numbers, nothing else
    first = asked[0]
    assert len(first) == 5 and all(np.count_nonzero(row != values) == 1 for row in first)
    assert got.simulations == 10 + 5 + 2
