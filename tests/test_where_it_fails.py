"""Where a layout's copies fail: ``evaluate`` names the event each failed copy failed at
first, so that a builder knows which step to build with care."""

import json
from pathlib import Path

import pytest

from rgmcad.runs.problem import ScenarioContext
from rgmcad.runs.robustness import CLOSE_IN, first_failure
from rgmcad.scene.design_space import values_from_mapping, vector_from_values
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges
from rgmcad.sim.run import Outcome
from tests._support import cli_output

RAMP = str(Path(__file__).parent / "data" / "ramp.toml")
HAND = PhysicsRanges(friction=0, mass=0, restitution=0, position=0.002, heading=1)


@pytest.fixture(scope="module")
def teapot():
    context = ScenarioContext.load("scenarios/teapot.toml")
    yield context
    context.close()


def test_the_first_failure_is_where_the_chain_broke(teapot):
    # teapot's `solved`, built by hand: most builds fail somewhere along the ball's tracks
    sc = teapot.scenario
    x = vector_from_values(sc, values_from_mapping(sc, sc.layouts["solved"]))
    failures = 0
    for draw in range(6):
        record = teapot.simulate_one(x, physics=PhysicsDraw(HAND, 0, draw))
        name = first_failure(record)
        if record.outcome is not Outcome.FAILURE:
            assert name is None
            continue
        failures += 1
        label, when = record.events[name]
        assert label is not True
        spec = sc.events[name]  # what it waited for happened, earlier
        happened = [record.events[c][0] is True and (when is None or record.events[c][1] <= when)
                    for c in spec.after]
        assert (any if spec.join == "any" else all)(happened)
        for other, (other_label, other_time) in record.events.items():  # nothing failed before
            assert not (other_label is False and when is not None and other_time < when), other
    assert failures >= 2



def test_evaluate_counts_every_failed_copy_once(tmp_path):
    # the block at the friction edge: placement errors never stop it, +-20 % friction does
    argv = ["evaluate", RAMP, "--layout", "edge", "--rho-g", "--samples", "8", "--workers", "1",
            "--out", str(tmp_path / "r.png")]
    code, out, _ = cli_output([*argv, "--json"])
    assert code == 0
    result = json.loads(out)
    counts = result["counts"]  # the same layouts under both kinds of error
    for fig in (result, result["physics"]):
        close = [c for (eps, *_), c in zip(fig["curve"], counts, strict=True) if eps <= CLOSE_IN]
        lost = [round(c * (1 - rho)) for (_, rho, *_), c in zip(fig["curve"], counts, strict=True)]
        close_in, everywhere = fig["failures"]["close_in"], fig["failures"]["all"]
        assert close_in["layouts"] == sum(close) and everywhere["layouts"] == sum(counts)
        assert sum(close_in["failed"].values()) == sum(lost[:len(close)])
        assert sum(everywhere["failed"].values()) == sum(lost)
        assert set(everywhere["failed"]) <= {"block_lands"}
    assert result["failures"]["close_in"]["failed"] == {}
    assert result["physics"]["failures"]["close_in"]["failed"]["block_lands"] > 0
    code, out, _ = cli_output(argv)
    lines = [line for line in out.splitlines() if "first failures" in line]
    assert len(lines) == 1 and lines[0].startswith("placement + physical errors")
    assert "block_lands" in lines[0]


def test_the_run_report_names_where_layouts_near_the_result_failed(tmp_path):
    run = tmp_path / "run"
    code, out, _ = cli_output(["optimize", RAMP, "--budget", "small", "--robustness", "4",
                               "--workers", "1", "--run", str(run), "--physics", "friction=0.6"])
    assert code == 0
    robustness = json.loads((run / "result.json").read_text())["robustness"]
    report = (run / "report.md").read_text()
    for fig, what in ((robustness, "placement errors"),
                      (robustness["physics"], "placement plus physical errors")):
        failed = fig["failures"]["close_in"]["failed"]
        lines = [line for line in report.splitlines()
                 if line.startswith(f"- under {what}, first failures")]
        said = [line for line in out.splitlines() if line.startswith(
            f"under {what.replace(' plus physical', ' + physical')}, first failures")]
        if failed:  # the block stays on the board when friction is up
            assert len(lines) == 1 and f"block_lands {failed['block_lands']}" in lines[0]
            assert len(said) == 1 and said[0].endswith(lines[0].split(", ", 1)[1])
        else:
            assert not lines and not said
    # the browser report's table of events has the same counts, one column
    page = (run / "report.html").read_text()
    counts = [fig["failures"]["close_in"]["failed"].get("block_lands", 0)
              for fig in (robustness, robustness["physics"])]
    assert "failed first, of 12 layouts within 0.1" in page
    table = page[page.index("<h2>Events</h2>"):]
    row = table[table.index("<code>block_lands</code>"):]
    assert row[:row.index("</tr>")].endswith(f"<td>{counts[0]} / {counts[1]}</td>")
