"""The replay page and the optimisation report page, without a browser (see test_browser.py
for what a browser shows): what is recorded, how faithfully the stored poses give the
simulated ones back, how big the page is, and what the commands write."""

import base64
import json
import re
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rgmcad.cli import main
from rgmcad.scene.bodies import load_parts
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.loader import load_scenario
from rgmcad.sim.run import simulate
from rgmcad.viewer.page import write_replay_html
from rgmcad.viewer.recording import record_replay, replay_payload
from tests._support import PARTS

ROOT = Path(__file__).resolve().parent.parent
SIMPLE = "scenarios/simple.toml"
SWITCH = "scenarios/causality_switch.toml"


def _layout(path, name="solved"):
    scenario = load_scenario(path)
    return scenario, values_from_mapping(scenario, scenario.layouts[name]), \
        load_parts(scenario, PARTS)


@pytest.fixture(scope="module")
def switch():
    scenario, values, parts = _layout(SWITCH)
    result, replay = record_replay(scenario, values, parts)
    return scenario, values, parts, result, replay


def _decode(payload, key, dtype, width):
    return np.frombuffer(base64.b64decode(payload[key]), dtype).reshape(payload["frames"], -1,
                                                                         width)


def test_recording_changes_nothing_in_the_run(switch):
    scenario, values, parts, recorded, _ = switch
    plain = simulate(scenario, values, parts)
    assert recorded.to_dict()["events"] == plain.to_dict()["events"]
    assert recorded.sim_time == plain.sim_time and recorded.outcome is plain.outcome


def test_poses_are_recorded_at_100_hz_from_start_to_end(switch):
    scenario, _, _, result, replay = switch
    assert replay.times[0] == 0.0 and replay.times[-1] == pytest.approx(result.sim_time)
    steps = np.diff(replay.times[:-1])
    assert np.allclose(steps, 0.01, atol=scenario.settings.timestep / 2)
    assert len(replay.bodies) == len(replay.poses[0]) == sum(
        not b.plane for b in _scene_bodies(scenario, switch[1]))


def _scene_bodies(scenario, values):
    from rgmcad.scene.bodies import make_scene

    return make_scene(scenario, values, load_parts(scenario, PARTS)).bodies.values()


def test_every_body_carries_its_cad_mesh_stored_once_per_part(switch):
    scenario, values, _, _, replay = switch
    payload = replay_payload(replay)
    bodies = [b for b in _scene_bodies(scenario, values) if not b.plane]
    for body, entry in zip(bodies, payload["bodies"], strict=True):
        mesh = payload["meshes"][entry["mesh"]]
        vertices = np.frombuffer(base64.b64decode(mesh["vertices"]), "<f4").reshape(-1, 3)
        faces = np.frombuffer(base64.b64decode(mesh["faces"]),
                              "<" + mesh["index"]).reshape(-1, 3)
        assert np.allclose(vertices, body.built.vertices, atol=1e-7)
        assert np.array_equal(faces, body.built.faces)
    assert len(payload["meshes"]) == len({id(b.built) for b in bodies}) < len(bodies)


def test_stored_poses_give_the_simulated_ones_back(switch):
    *_, replay = switch
    payload = replay_payload(replay)
    moving = payload["moving"]
    assert moving and all(not replay.static[b] for b in moving)
    half = np.asarray(payload["half"])
    pos = np.asarray(payload["centre"]) + _decode(payload, "positions", "<i2", 3) / 32767 * half
    quat = _decode(payload, "quaternions", "<i2", 4) / 32767
    truth = replay.poses[:, moving]
    assert np.abs(pos - truth[..., :3, 3]).max() <= half.max() / 32767 + 1e-9  # < 0.1 mm here
    rot = Rotation.from_quat(quat.reshape(-1, 4)).as_matrix().reshape(truth[..., :3, :3].shape)
    angle = np.arccos(np.clip((np.einsum("...ii", np.swapaxes(rot, -1, -2) @ truth[..., :3, :3])
                               - 1) / 2, -1, 1))
    assert np.degrees(angle).max() < 0.02
    # a domino that topples really moves in the recording
    travel = np.linalg.norm(truth[-1, :, :3, 3] - truth[0, :, :3, 3], axis=1)
    assert travel.max() > 0.01


def test_a_10_s_run_of_causality_switch_stays_under_10_mb(switch, tmp_path):
    *_, replay = switch
    frames = 1001  # 10 s at 100 Hz: the page grows with the frames, not with what moves
    reps = -(-frames // len(replay.times))
    long = replace(replay, times=np.arange(frames) * 0.01,
                   poses=np.concatenate([replay.poses] * reps)[:frames])
    start = time.perf_counter()
    path = write_replay_html(tmp_path / "long.html", long)
    took = time.perf_counter() - start
    size = path.stat().st_size
    print(f"10 s of causality_switch ({len(long.bodies)} bodies): {size / 1e6:.2f} MB, "
          f"written in {took:.2f} s")
    assert size < 10e6


def test_simulate_html_writes_a_self_contained_page(tmp_path, capsys):
    out = tmp_path / "cs.html"
    assert main(["simulate", SWITCH, "--layout", "solved", "--html", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["html"] == str(out)
    text = out.read_text()
    assert not re.search(r"""(src|href)=["']?(https?:|//)""", text)  # nothing fetched
    assert "Copyright 2010-2026 Three.js Authors" in text
    for e in summary["events"]:
        assert f'data-event="{e["name"]}" data-state="{e["state"]}"' in text
    assert out.stat().st_size < 10e6


def test_a_replay_stopped_with_until_ends_there(tmp_path, capsys):
    def replay_end(until):
        out = tmp_path / f"u{until}.html"
        argv = ["simulate", SIMPLE, "--layout", "solved", "--html", str(out), "--json"]
        main([*argv, *([] if until is None else ["--until", str(until)])])
        events = {e["name"]: e["state"] for e in json.loads(capsys.readouterr().out)["events"]}
        return float(re.search(r"frames, ([\d.]+) s simulated", out.read_text())[1]), events

    whole, all_events = replay_end(None)
    stopped, events = replay_end(0.3)
    assert 0.25 < stopped <= 0.3 < whole
    assert set(all_events.values()) == {"success"} and set(events.values()) != {"success"}


@pytest.mark.parametrize("name", ["out.txt", "missing-folder/out.html"])
def test_bad_html_path_gives_one_line_and_exit_2(name, tmp_path, capsys):
    assert main(["simulate", SIMPLE, "--html", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--html" in err


def test_an_invalid_layout_gets_a_page_naming_the_overlap(tmp_path, capsys):
    out = tmp_path / "bad.html"
    main(["simulate", SIMPLE, "--vector", "0,0,0", "--html", str(out)])
    assert "overlap" in out.read_text() and "invalid" in capsys.readouterr().out


@pytest.fixture(scope="module")
def optimized(tmp_path_factory):
    run = tmp_path_factory.mktemp("opt") / "run"
    code = main(["optimize", SIMPLE, "--budget", "small", "--run", str(run), "--workers", "1",
                 "--json"])
    assert code in (0, 1)
    return run, json.loads((run / "result.json").read_text())


def test_optimize_writes_a_report_page(optimized):
    run, summary = optimized
    text = (run / "report.html").read_text()
    assert 'id="rgmcad-replay"' in text
    for event, p in summary["event_probabilities"].items():
        assert f"<code>{event}</code>" in text and f"{p:.3f}" in text
    assert "(weakest link)" in text and summary["weakest_event"] in text
    scenario = load_scenario(SIMPLE)
    for f in scenario.free:  # every parameter in mm or degrees
        unit = "deg" if f.unit == "deg" else "mm"
        k = 1.0 if unit == "deg" else 1000.0
        assert f"{summary['values'][f.name] * k:.1f} {unit}" in text
    steps = text.count('alt="step ')  # the assembly steps' pictures (rgmcad.viewer.making)
    assert steps >= 3 and text.count("data:image/png;base64,") == 3 + steps  # and 3 figures
    assert "<h2>Bill of materials</h2>" in text and "## Assembly steps" in (run / "report.md").read_text()
    assert 'href="layout.json"' in text


def test_the_report_links_the_template_once_it_is_made(optimized, capsys):
    run, summary = optimized
    assert 'href="template/template.pdf"' not in (run / "report.html").read_text()
    assert main(["template", SIMPLE, "--layout", str(run / "layout.json"),
                 "--out", str(run / "template")]) == 0
    main(["optimize", SIMPLE, "--budget", "small", "--run", str(run), "--workers", "1"])
    capsys.readouterr()
    assert 'href="template/template.pdf"' in (run / "report.html").read_text()


def test_the_report_s_template_command_works_pasted_anywhere(optimized, tmp_path, monkeypatch):
    # a user's own scenario (not shipped, so its name alone finds nothing), a relative run
    # directory, and the command pasted in another folder
    import html
    import shlex
    import shutil

    from rgmcad.viewer.report import write_run_report

    run, _ = optimized
    mine = tmp_path / "my machine" / "marble.toml"
    mine.parent.mkdir()
    mine.write_text((ROOT / SIMPLE).read_text().replace('name = "simple"', 'name = "marble"', 1))
    monkeypatch.chdir(tmp_path)
    shutil.copytree(run, "copy", ignore=shutil.ignore_patterns("template"))  # none made yet
    result = json.loads(Path("copy/result.json").read_text())
    result["layout"] = "copy/layout.json"
    Path("copy/result.json").write_text(json.dumps(result))
    layout = json.loads(Path("copy/layout.json").read_text())
    Path("copy/layout.json").write_text(json.dumps({**layout, "scenario": "marble"}))
    page = write_run_report(Path("copy"), Path("my machine/marble.toml")).read_text()
    command = shlex.split(html.unescape(re.search(r"<pre>(rgmcad template .*?)</pre>",
                                                  page).group(1)))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(command[1:]) == 0
    assert (tmp_path / "copy" / "template" / "template.pdf").is_file()


def test_tight_tolerances_are_highlighted(optimized):
    from rgmcad.viewer.report import TIGHT_DEG, TIGHT_MM

    run, summary = optimized
    text = (run / "report.html").read_text()
    for f in load_scenario(SIMPLE).free:
        k, limit = (1.0, TIGHT_DEG) if f.unit == "deg" else (1000.0, TIGHT_MM)
        pushed = (summary.get("push_against") or {}).get(f.name, {})
        tight = any(t * k < limit and side not in pushed  # pushing against a part is easy
                    for t, side in zip(summary["tolerances"][f.name], ("low", "high"),
                                       strict=True))
        assert (f'<tr class="tight"><td><code>{f.name}</code>' in text) == tight


def test_an_or_join_reads_as_one_in_the_replay(tmp_path, capsys):
    # a user read "after a, b" on an event that waits for either, as if it waited for both
    out = tmp_path / "or.html"
    assert main(["simulate", "tools/generality/split_seesaw.toml", "--layout", "hand",
                 "--html", str(out), "-q"]) == 0
    text = out.read_text()
    assert "after the first of ball_in_box or cylinder_in_box" in text


def test_a_part_has_one_colour_in_the_png_the_video_the_replay_and_the_report(
        optimized, tmp_path, monkeypatch):
    # each picture once drew its own colours (a ball and a domino shared a pink)
    from rgmcad.sim.render import Renderer

    drawn = []  # the colour table of every renderer made: the PNG's, then the video's
    close = Renderer.close
    monkeypatch.setattr(Renderer, "close", lambda self: (drawn.append(self.colours),
                                                         close(self)))
    size = ["--width", "48", "--height", "32"]
    assert main(["render", SIMPLE, "--out", str(tmp_path / "s.png"), *size]) == 0
    assert main(["simulate", SIMPLE, "--video", str(tmp_path / "s.gif"), *size, "-q"]) == 0
    scenario, values, parts = _layout(SIMPLE)
    recorded = record_replay(scenario, values, parts)[1]
    replay = replay_payload(recorded)
    run, _ = optimized
    report = json.loads(re.search(r'id="rgmcad-replay-data">(.*?)</script>',
                                  (run / "report.html").read_text())[1])
    png, video = ({name: [round(c, 3) for c in rgb] for name, rgb in t.items()} for t in drawn)
    for page in (replay, report):
        assert {b["name"]: b["color"] for b in page["bodies"]} == png == video
    assert png["ball"] != png["run[0]"]
    # the viewer's labels: an object's name, a domino run's name for its dominoes
    assert [b["label"] for b in replay["bodies"]] == ["ball", "track", "run", "run", "run"]
    unlabelled = replace(recorded, labels=None)  # a replay made elsewhere (rgmcad live)
    assert replay_payload(unlabelled)["bodies"] == replay["bodies"]
    assert replay["plane_colors"] == [[0.871, 0.859, 0.831]]  # the floor, grey
