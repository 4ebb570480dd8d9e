"""A layout whose placement tolerance stops at the end of a parameter's range, or where parts
would overlap: ``rgmcad optimize`` says so where the user reads the tolerances (the printed
summary, report.md, report.html, the printed template) and tells them what it means."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from rgmcad.learning import range_ends
from rgmcad.runs.report import ROUGH_MODEL, tolerance_notes
from tests._support import cli_output


def _down(v: float) -> str:
    """A tolerance as printed: rounded down to 0.1 (the number read stays inside the bound)."""
    return f"{math.floor(v * 10 + 1e-6) / 10:.1f}"

ROOT = Path(__file__).resolve().parent.parent


def _one_parameter_simple(tmp_path: Path) -> Path:
    """simple with only the track's roll free, over 15-75 degrees: the chain works from about
    9 to 40 degrees, so the most robust layout in the range sits near its low end, and the
    model knows nothing below it."""
    text = (ROOT / "scenarios" / "simple.toml").read_text()
    for old, new in (("free = { x = [-0.15, 0.0], z = [0.0, 0.15], roll = [15, 75] }",
                      "free = { roll = [15, 75] }"),
                     ("track = { x = -0.1, z = 0.1, roll = 30 }", "track = { roll = 30 }")):
        assert old in text  # the shipped scenario changed: update this test's edit
        text = text.replace(old, new)
    path = tmp_path / "roll_only.toml"
    path.write_text(text)
    return path


def test_a_tolerance_stopped_by_the_range_is_marked_and_the_user_told_to_widen_it(tmp_path):
    scenario = _one_parameter_simple(tmp_path)
    run = tmp_path / "run"
    code, out, err = cli_output(["optimize", str(scenario), "--budget", "small", "--run",
                                 str(run), "-q"])
    assert code == 0, err
    summary = json.loads((run / "result.json").read_text())
    down, up = summary["tolerances"]["track.roll"]
    roll = summary["values"]["track.roll"]
    # the law: marked on a side exactly when the tolerance there reaches the range's end
    assert summary["range_ends"].get("track.roll") in ("low", "both")
    assert abs(roll - down - 15.0) < 1e-9
    assert (abs(roll + up - 75.0) < 1e-9) == (summary["range_ends"]["track.roll"] == "both")
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("track.roll"))
    assert f"-{_down(down)} (end of range) /" in line
    assert "note: a tolerance marked 'end of range'" in out and "widen that range" in out
    for name in ("report.md", "report.html"):
        text = (run / name).read_text()
        assert f"{_down(down)} (end of range)" in text and "widen that range" in text, name
    # the same run directory shown again (finished): the same words
    code, again, _ = cli_output(["optimize", str(scenario), "--budget", "small", "--run",
                                 str(run), "-q"])
    assert code == 0 and line in again and "widen that range" in again


def test_a_tolerance_inside_the_range_is_not_marked():
    x = np.array([0.5, 0.0, 0.97, 0.4])
    tol = np.array([[0.1, 0.2], [0.0, 0.3], [0.2, 0.03], [0.4, 0.6]])
    assert range_ends(x, tol) == [None, "low", "high", "both"]


def test_a_tolerance_stops_where_parts_would_meet_and_says_so(tmp_path):
    # the user moves the crate by the tolerance the run printed, then a little further (two
    # workers: the tolerances are written once the simulation pool has closed)
    scenario = ROOT / "tests" / "data" / "crate_by_post.toml"
    run = tmp_path / "run"
    code, out, err = cli_output(["optimize", str(scenario), "--budget", "small", "--run",
                                 str(run), "-q", "--workers", "2"])
    assert code == 0, err
    summary = json.loads((run / "result.json").read_text())
    x = summary["values"]["crate.x"]
    down, up = summary["tolerances"]["crate.x"]
    # the crate (4 cm) meets the posts (2 cm, at 0 and 0.24 m) at x = 0.03 and 0.21 m, give
    # or take the validity test's 0.2 mm
    assert 0.0297 <= x - down <= 0.0305 and 0.2095 <= x + up <= 0.2103, (x - down, x + up)
    assert summary["overlap_ends"] == {"crate.x": "both"}
    line = next(ln for ln in out.splitlines() if ln.strip().startswith("crate.x"))
    # pushed against a post, the crate works: no number, where to push
    assert line.endswith("push against the left_post / push against the post")
    assert summary["push_against"] == {"crate.x": {"low": "left_post", "high": "post"}}
    assert "note: 'push against the X'" in out and "parts meet" not in out
    for name in ("report.md", "report.html"):
        assert "push against the post" in (run / name).read_text(), name
    layout = str(run / "layout.json")
    for to, code_expected, word in ((x + up - 0.0005, 0, "success"), (x + up + 0.0005, 1,
                                    "invalid"), (x - down + 0.0005, 0, "success"),
                                    (x - down - 0.0005, 1, "invalid")):
        code, out, _ = cli_output(["-q", "simulate", str(scenario), "--layout", layout,
                                   "--value", f"crate.x={to}"])
        assert code == code_expected and f"outcome: {word}" in out, out
    # the printed template says where to push, not "not limiting within the range"
    code, _, err = cli_output(["template", str(scenario), "--layout", layout, "--out",
                               str(tmp_path / "tpl"), "-q"])
    assert code == 0, err
    svg = (tmp_path / "tpl" / "template.svg").read_text()
    assert ("x: below: push against the left_post; above: push against the post" in svg
            and "not limiting" not in svg)


def test_tolerances_of_a_rough_model_come_with_a_caution():
    # a small budget's model that rates its own verified layout 0.07 (a user's 8-parameter
    # scenario did): its tolerances are only as good as it is
    s = {"probability": 0.066, "verified": True, "budget": "small"}
    (note,) = tolerance_notes(s)
    assert "rates this layout's success at 0.07" in note and "rgmcad evaluate" in note
    assert "default budget" in note
    assert "default budget" not in tolerance_notes({**s, "budget": "default"})[0]
    assert tolerance_notes({**s, "probability": ROUGH_MODEL}) == []
    assert tolerance_notes({**s, "verified": False}) == []  # no layout succeeded: said apart
