"""The command line: shipped scenarios, JSON output, and one-line errors with exit status 2."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from _support import cli_output, run

from rgmcad.cli import main
from rgmcad.scene.loader import load_scenario

SCENARIOS = sorted(Path("scenarios").glob("*.toml"))


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_solved_layout_of_every_shipped_scenario_succeeds(path, capsys):
    assert main(["simulate", str(path), "--layout", "solved", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["outcome"] == "success"
    assert {"outcome", "events", "sim_time", "wall_time"} <= set(out)
    assert all(e["state"] == "success" for e in out["events"])


def test_check_prints_a_summary(capsys):
    assert main(["check", "scenarios/causality_switch.toml"]) == 0
    out = capsys.readouterr().out
    assert "d = 4" in out and "switch_run.y" in out and "solved: valid" in out


def _write(tmp_path, text, name="bad.toml"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


GOOD = Path("scenarios/simple.toml").read_text()

BAD_FILES = {
    "unknown key": GOOD.replace("friction = 0.5\nrestitution = 0.2",
                                "friction = 0.5\nbounciness = 0.2"),
    "unknown part": GOOD.replace('part = "track"', 'part = "rail"'),
    "unknown event type": GOOD.replace('type = "stopping"', 'type = "halting"'),
    "event names a missing object": GOOD.replace('second = "run[0]"', 'second = "run[7]"'),
    "cycle in the graph": GOOD.replace(
        '[events.ball_rolls_on_track]\ntype = "rolling_on"',
        '[events.ball_rolls_on_track]\nafter = ["last_dom_stops"]\ntype = "rolling_on"'),
    "range min > max": GOOD.replace("z = [0.0, 0.15]", "z = [0.15, 0.0]"),
    "not TOML": "name = [",
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_scenario_gives_one_line_and_exit_2(case, tmp_path, capsys):
    path = _write(tmp_path, BAD_FILES[case])
    assert main(["check", path]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and path in err


@pytest.mark.parametrize("args", [
    ["simulate", "missing.toml"],
    ["simulate", "scenarios/simple.toml", "--vector", "0.5,0.5"],
    ["simulate", "scenarios/simple.toml", "--vector", "0.5,0.5,1.5"],
    ["simulate", "scenarios/simple.toml", "--vector", "a,b,c"],
    ["simulate", "scenarios/simple.toml", "--layout", "nonexistent"],
])
def test_bad_arguments_give_one_line_and_exit_2(args, capsys):
    assert main(args) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_layout_file_for_another_scenario_is_refused(tmp_path, capsys):
    path = _write(tmp_path, json.dumps({"scenario": "ballrun", "vector": [0.5] * 3}),
                  "layout.json")
    assert main(["simulate", "scenarios/simple.toml", "--layout", path]) == 2
    assert "ballrun" in capsys.readouterr().err


def test_layout_file_round_trip(tmp_path, capsys):
    path = _write(tmp_path, json.dumps({"scenario": "simple",
                                        "values": {"track.x": -0.1, "track.z": 0.1}}),
                  "layout.json")
    assert main(["simulate", "scenarios/simple.toml", "--layout", path, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["outcome"] == "success"


def test_same_vector_gives_identical_timeline_in_two_processes():
    cmd = [sys.executable, "-m", "rgmcad.cli", "simulate", "scenarios/causality_switch.toml",
           "--vector", "0.9,0.3,0.6,0.5", "--json"]
    done = [subprocess.run(cmd, capture_output=True, text=True) for _ in range(2)]
    assert [d.returncode for d in done] in ([0, 0], [1, 1])  # success, or the same failure
    runs = [json.loads(d.stdout) for d in done]
    assert runs[0]["events"] == runs[1]["events"]
    assert runs[0]["sim_time"] == runs[1]["sim_time"]


def test_render_and_video(tmp_path):
    png, gif = tmp_path / "a.png", tmp_path / "a.gif"
    assert main(["render", "scenarios/simple.toml", "--out", str(png), "--width", "160",
                 "--height", "120"]) == 0
    assert main(["simulate", "scenarios/simple.toml", "--video", str(gif), "--width", "96",
                 "--height", "72"]) == 0
    from PIL import Image

    image = Image.open(png)
    pixels = np.asarray(image).reshape(-1, len(image.getbands()))
    assert image.size == (160, 120) and len(np.unique(pixels, axis=0)) > 10
    assert Image.open(gif).n_frames > 5


# --- events: negate, hold, join, timeout, point / end ----------------------------------------

def _event(text):
    """simple.toml with one more event after the root (and event_timeout 1.5 s)."""
    return (GOOD.replace("duration = 3.0", "duration = 3.0\nevent_timeout = 1.5")
            + "\n[events.extra]\nafter = [\"ball_rolls_on_track\"]\n" + text)


def _rows(out):
    """check's event table: {event name: its cells}."""
    table = out.split("\nevents (")[1].split("\n\n")[0].splitlines()[1:]
    header = table[0]
    starts = [header.index(h) for h in ("event", "type", "objects", "after", "join", "negate",
                                        "hold (s)", "timeout (s)")]
    return {row.split()[0]: [row[a:b].strip() for a, b in zip(starts, [*starts[1:], None],
                                                               strict=True)]
            for row in table[1:]}


def test_check_shows_negate_hold_join_and_timeout_of_every_event(tmp_path, capsys):
    text = _event('type = "rising"\nbody = "ball"\nend = "+z"\nnegate = "always"\n'
                  "timeout = 0.5\nhold = 0.1\n")
    text = text.replace('type = "stopping"', 'type = "stopping"\nnegate = true\nhold = 0.25')
    text = text.replace('after = ["last_dom_topples"]',
                        'after = ["last_dom_topples", "extra"]\njoin = "any"')
    assert main(["check", _write(tmp_path, text)]) == 0
    rows = _rows(capsys.readouterr().out)
    assert rows["extra"] == ["extra", "rising", "ball (end +z)", "ball_rolls_on_track", "all",
                             "always", "0.1", "0.5"]
    assert rows["last_dom_stops"][3:] == ["last_dom_topples | extra", "any", "true", "0.25",
                                          "1.5 (default)"]
    assert rows["ball_rolls_on_track"][3:] == ["(root)", "-", "false", "0", "1.5 (default)"]


def test_check_shows_a_point_given_by_coordinates(tmp_path, capsys):
    text = _event('type = "falling"\nbody = "ball"\npoint = { x = 0.01, z = -0.005 }\n')
    assert main(["check", _write(tmp_path, text)]) == 0
    assert _rows(capsys.readouterr().out)["extra"][2] == "ball (point 0.01, 0, -0.005)"


BAD_EVENTS = {  # (scenario text, the key the error names, a word of what is allowed)
    "hold = timeout": (_event('type = "falling"\nbody = "ball"\ntimeout = 1.0\nhold = 1.0\n'),
                       "events.extra.hold", "0 <= hold < 1 s, the event's timeout"),
    "hold > default timeout": (_event('type = "falling"\nbody = "ball"\nhold = 2\n'),
                               "events.extra.hold", "< 1.5 s, the event's timeout (the scenario's"),
    "negative hold": (_event('type = "falling"\nbody = "ball"\nhold = -0.1\n'),
                      "events.extra.hold", "0 <= hold"),
    "unknown end": (_event('type = "rising"\nbody = "ball"\nend = "top"\n'),
                    "events.extra.end", '"+x", "-x", "+y", "-y", "+z", "-z"'),
    "point with an unknown key": (_event('type = "rising"\nbody = "ball"\npoint = { w = 1 }\n'),
                                  "events.extra.point.w", "allowed: x, y, z"),
    "point with a string": (_event('type = "rising"\nbody = "ball"\npoint = { x = "1" }\n'),
                            "events.extra.point.x", "expected a number"),
    "point is not a table": (_event('type = "rising"\nbody = "ball"\npoint = [0, 0, 1]\n'),
                             "events.extra.point", "x = ..., y = ..., z = ..."),
    "point and end": (_event('type = "rising"\nbody = "ball"\nend = "+x"\npoint = { x = 1 }\n'),
                      "events.extra.point", "point or end, not both"),
    "end of an event about attitude": (
        _event('type = "toppling"\nbody = "ball"\nangle = 10\nend = "+x"\n'),
        "events.extra.end", "takes no point or end (only falling, rising do)"),
    "end of a plane": (_event('type = "rising"\nbody = "floor"\nend = "+x"\n'),
                       "events.extra.end", "infinite plane"),
    "unknown negate": (_event('type = "falling"\nbody = "ball"\nnegate = "never"\n'),
                       "events.extra.negate", 'true, false or "always"'),
    "always outlasting the run": (
        _event('type = "falling"\nbody = "ball"\nnegate = "always"\ntimeout = 3.0\n'),
        "events.extra.timeout", "shorter than the simulation's duration"),
}


@pytest.mark.parametrize("case", sorted(BAD_EVENTS))
def test_bad_event_gives_one_line_naming_the_key_and_exit_2(case, tmp_path, capsys):
    text, key, allowed = BAD_EVENTS[case]
    path = _write(tmp_path, text)
    assert main(["check", path]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith(f"rgmcad: error: {path}: {key}: ") and allowed in err, err


def test_bad_event_exit_status_from_the_command_line(tmp_path):
    path = _write(tmp_path, BAD_EVENTS["hold = timeout"][0])
    done = subprocess.run([sys.executable, "-m", "rgmcad.cli", "check", path],
                          capture_output=True, text=True)
    assert done.returncode == 2 and "events.extra.hold" in done.stderr
    assert len([line for line in done.stderr.splitlines() if "rgmcad" in line]) == 1


def test_simulate_json_says_where_every_body_ended(capsys):
    # A user looking for where a ball went reads it from --json instead of rendering a video.
    assert main(["simulate", "scenarios/simple.toml", "--layout", "solved", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ends = out["final_poses"]
    assert {"floor", "ball", "track", "run[0]", "run[1]", "run[2]"} <= set(ends)
    ball, track = ends["ball"], ends["track"]
    # The track is fixed: it ends where the layout put it, to the micrometre.
    assert track["x"] == pytest.approx(out["values"]["track.x"], abs=1e-6)
    assert track["roll"] == pytest.approx(out["values"]["track.roll"], abs=1e-3)
    # The ball (radius 10 mm) rolled off the track, which the layout holds above the floor,
    # and lies on the floor, past the track's lower end.
    assert ball["z"] == pytest.approx(0.01, abs=1e-3)
    assert ball["x"] > track["x"]
    # Every domino toppled (the scenario's toppling events), so none stands upright.
    for name in ("run[0]", "run[1]", "run[2]"):
        tilt = max(abs(ends[name]["pitch"]), abs(ends[name]["roll"]))
        assert tilt > 15, (name, ends[name])
    # Watching the run does not change it: the events are those of a plain simulation.
    scenario = load_scenario(Path("scenarios/simple.toml"))
    plain = run(scenario, "solved")
    assert [[e.name, e.state.value, e.time] for e in plain.events] == [
        [e["name"], e["state"], e["time"]] for e in out["events"]]


def test_simulate_until_shows_where_bodies_are_part_way(capsys):
    # A user checks that the see-saw was still level before the ball struck it, by stopping
    # the run part way; the scenario's negate = "always" leaf (timeout 1 s) refuses a copy of
    # the file with a shorter duration, --until does not.
    held_out = "tools/generality/split_seesaw.toml"
    assert main(["simulate", held_out, "--layout", "hand", "--json"]) == 0
    whole = json.loads(capsys.readouterr().out)
    times = {e["name"]: e["time"] for e in whole["events"]}
    until = round(times["ball_hits_seesaw"] - 0.1, 3)
    assert main(["simulate", held_out, "--layout", "hand", "--until", str(until), "--json"]) == 1
    part = json.loads(capsys.readouterr().out)
    assert part["sim_time"] == pytest.approx(until, abs=0.002)
    # the events up to then are the whole run's; the later ones did not happen
    for early, late in zip(part["events"], whole["events"], strict=True):
        if late["time"] is not None and late["time"] <= until:
            assert early == late
        else:
            assert early["state"] != "success"
    # the see-saw still at its start, the ball above it; at the end, tipped the other way
    # and the ball low in the box
    assert main(["simulate", held_out, "--layout", "hand", "--until", "0.002", "--json"]) == 1
    seesaw_start = json.loads(capsys.readouterr().out)["final_poses"]["seesaw"]["roll"]
    assert abs(seesaw_start) > 10  # it starts tilted, its -X end raised
    assert part["final_poses"]["seesaw"]["roll"] == pytest.approx(seesaw_start, abs=0.5)
    assert part["final_poses"]["seesaw"]["roll"] * whole["final_poses"]["seesaw"]["roll"] < 0
    assert part["final_poses"]["ball"]["z"] > whole["final_poses"]["ball"]["z"] + 0.05
    # at the scenario's own duration it is the plain run
    assert main(["simulate", held_out, "--layout", "hand", "--until", "4", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["events"] == whole["events"]
    for bad in ("0", "-1", "4.5"):
        code, out, err = cli_output(["simulate", held_out, "--until", bad])
        assert code == 2 and not out and err.count("\n") == 1
        assert "--until" in err and "(0, 4]" in err


def test_value_sweeps_one_parameter_as_a_layout_file_would(tmp_path, capsys):
    # A user sweeping box.x by hand: each --value run is the run of a layout file holding
    # the hand layout with that one value changed (what they had to write before).
    held_out = "tools/generality/split_seesaw.toml"
    assert main(["simulate", held_out, "--layout", "hand", "--json"]) == 0
    hand = json.loads(capsys.readouterr().out)["values"]
    outcomes = set()
    for x in (-0.25, -0.15, hand["box.x"]):
        code = main(["simulate", held_out, "--layout", "hand", "--value", f"box.x={x}", "--json"])
        swept = json.loads(capsys.readouterr().out)
        file = tmp_path / f"box{x}.json"
        file.write_text(json.dumps({"values": {**hand, "box.x": x}}))
        assert main(["simulate", held_out, "--layout", str(file), "--json"]) == code
        written = json.loads(capsys.readouterr().out)
        assert swept["values"] == written["values"] == {**hand, "box.x": x}
        assert swept["events"] == written["events"]
        assert swept["layout"] == f"hand, box.x={x}"
        outcomes.add(swept["outcome"])
    assert outcomes == {"success", "failure"}  # the sweep crossed the edge of what works
    # the same flag poses an exported layout
    out = tmp_path / "moved.glb"
    code, text, _ = cli_output(["export", held_out, "--layout", "hand", "--value", "box.x=-0.15",
                                "--out", str(out)])
    assert code == 0 and "box.x=-0.15" in text and out.stat().st_size > 0
    for bad, says in (("nope=1", "a free parameter"), ("box.x", "a free parameter"),
                      ("box.x=abc", "a number"), ("box.x=nan", "finite")):
        code, text, err = cli_output(["simulate", held_out, "--value", bad])
        assert code == 2 and not text and err.count("\n") == 1 and says in err, err


def test_simulate_json_of_an_invalid_layout_has_no_poses(capsys):
    assert main(["simulate", "scenarios/simple.toml", "--vector", "0,0,0.5", "--json"]) == 1
    out = json.loads(capsys.readouterr().out)
    assert out["outcome"] == "invalid" and "final_poses" not in out


def test_a_success_that_needed_one_alternative_says_so(tmp_path, capsys):
    # an OR-join's other branch never happens (the first domino never touches the track):
    # the run succeeds, and "5/6 events" alone read like a failure to a user
    text = _event('type = "contact"\nfirst = "run[0]"\nsecond = "track"\n')
    text = text.replace('after = ["last_dom_topples"]',
                        'after = ["last_dom_topples", "extra"]\njoin = "any"')
    assert main(["simulate", _write(tmp_path, text)]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("outcome: success (5/6 events, the other 1 not needed (alternatives)")


def test_a_value_far_outside_its_range_is_warned_of_naming_the_key(caplog):
    # 17 typed for 17 mm: the cup would be 17 m away; simulated, as asked, with one warning
    from tests._support import cli_output

    code, out, _ = cli_output(["simulate", "simple", "--value", "track.z=17"])
    warnings = [r.getMessage() for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and warnings[0].startswith("--value track.z=17 m is "), warnings
    assert "millimetres written as metres?" in warnings[0] and "outcome:" in out
    caplog.clear()
    cli_output(["simulate", "simple", "--value", "track.z=0.2"])  # just past its range
    assert not [r for r in caplog.records if r.levelname == "WARNING"]
