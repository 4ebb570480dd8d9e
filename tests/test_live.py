"""``rgmcad live`` without a browser: the real command as a subprocess (its routes, what it
binds to, its file watching, its WebSocket, Ctrl-C), and the worker's and the views' pieces
in this process."""

from __future__ import annotations

import http.client
import json
import os
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import psutil
import pytest

from rgmcad.live import worker
from rgmcad.live.errors import key_line
from rgmcad.live.files import Watcher, read_saved, watched_files, write_saved
from rgmcad.live.views import side_by_side, still_replay
from tests._live import BROKEN, FAILING, SIMPLE, TRACK, Server
from tests._support import cli_output, popen_as_terminal


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    s = Server(tmp_path_factory.mktemp("live"))
    yield s
    code, out, err = s.stop()
    assert code == 0 and out.splitlines()[-1] == "stopped", (out, err)
    assert "Traceback" not in err and "pybullet build time" not in out + err, err


@pytest.fixture
def fresh(server):
    """The module's server, its scenario as shipped again."""
    server.write(server.original)
    return server


def _get(server, path: str, headers=None) -> tuple[int, bytes]:
    """A raw GET of ``path``, sent as written (no normalisation of ``..``)."""
    host, port = server.url.split("//")[1].strip("/").split(":")
    conn = http.client.HTTPConnection(host, int(port), timeout=10)
    conn.putrequest("GET", path, skip_host=bool(headers and "Host" in headers))
    for k, v in (headers or {}).items():
        conn.putheader(k, v)
    conn.endheaders()
    r = conn.getresponse()
    return r.status, r.read()


def test_the_address_is_printed_and_only_localhost_is_listened_on(server):
    assert server.url.startswith("http://127.0.0.1:")
    port = int(server.url.rstrip("/").rsplit(":", 1)[1])
    listening = [c.laddr for c in psutil.Process(server.proc.pid).net_connections("tcp")
                 if c.status == psutil.CONN_LISTEN]
    assert [(a.ip, a.port) for a in listening] == [("127.0.0.1", port)]
    assert server.ready["main"]["outcome"] == "success"
    assert server.ready["took"] < 30  # the first simulation starts the worker


def test_only_the_fixed_routes_answer_and_no_path_reaches_the_file_system(server):
    for path, kind in (("/", b"<!DOCTYPE html>"), ("/live.js", b"WebSocket"),
                       ("/live.css", b"body"), ("/view", b"rgmcad-replay-data"), ("/state", b"{")):
        status, body = _get(server, path)
        assert status == 200 and kind in body, path
    secret = server.file.parent / "secret.txt"
    secret.write_text("do not serve me")
    for path in ("/../../etc/passwd", "/%2e%2e/%2e%2e/etc/passwd", "/..%2f..%2fetc%2fpasswd",
                 "/%252e%252e/%252e%252e/etc/passwd", "//etc/passwd", "/view/../../etc/passwd",
                 "/live.js/../../../etc/passwd", "/..\\..\\etc\\passwd", "/etc/passwd",
                 f"/{secret.name}", f"/..%2f{secret.name}", f"/view?file={secret}",
                 "/static/../simple.toml", "/simple.toml", "/%00", "/assets/live.js"):
        status, body = _get(server, path)
        if path.startswith("/view?"):  # a query names nothing: the page, whatever it says
            assert status == 200 and b"do not serve me" not in body
            continue
        assert status in (400, 404), (path, status)
        assert b"root:" not in body and b"do not serve me" not in body and b"[objects" not in body


def test_a_foreign_host_or_origin_is_refused(server):
    assert _get(server, "/", {"Host": "attacker.example:80"})[0] == 403
    assert _get(server, "/state", {"Host": "127.0.0.1.attacker.example"})[0] == 403
    import aiohttp

    with pytest.raises(aiohttp.WSServerHandshakeError) as refused:
        server.talk([], origin="http://attacker.example")
    assert refused.value.status == 403
    assert server.talk([], origin=server.url.rstrip("/"))[0]["type"] == "state"


def test_a_save_shows_the_new_outcome_within_two_seconds(fresh):
    s = fresh.edit(TRACK, FAILING)
    assert s["main"]["outcome"] == "failure" and s["main"]["fails_at"] == "last_dom_topples"
    assert s["info"]["free"][2] == {"name": "track.roll", "unit": "deg", "low": 15.0,
                                    "high": 75.0, "value": 60.0, "changed": False}
    print(f"save to result: {s['took']:.3f} s")
    assert s["took"] < 2.0
    s = fresh.edit(TRACK, TRACK.replace("z = 0.1", "z = 0.0"))  # the track in the floor
    assert s["main"]["outcome"] == "invalid"
    depth = pytest.approx(26.3, abs=0.01)
    assert s["main"]["overlaps"] == [{"first": "floor", "second": "track", "depth_mm": depth}]


def test_a_broken_file_shows_the_cli_error_line_and_a_fixed_one_recovers(fresh):
    s = fresh.write(fresh.original + BROKEN)
    code, _, err = cli_output(["check", str(fresh.file)])
    assert code == 2 and s["error"]["text"] == err.strip()
    assert s["error"]["line"] == len(fresh.original.splitlines()) + 2
    s = fresh.edit("duration = 3.0", "duration = -3.0")  # loads as TOML, refused by the loader
    code, _, err = cli_output(["check", str(fresh.file)])
    assert code == 2 and s["error"]["text"] == err.strip()
    assert fresh.original.splitlines()[s["error"]["line"] - 1] == "duration = 3.0"
    s = fresh.write(fresh.original)
    assert s["error"] is None and s["main"]["outcome"] == "success"


def test_sliders_sweep_and_save_over_the_websocket(fresh, tmp_path):
    states = fresh.talk([{"type": "sweep", "name": "track.roll", "points": 5}],
                        until=lambda s: (s.get("sweep") or {}).get("done"))
    sweep = states[-1]["sweep"]
    assert [p["value"] for p in sweep["points"]] == [15.0, 30.0, 45.0, 60.0, 75.0]
    assert sweep["points"][1]["outcome"] == "success"
    assert sweep["points"][3] | {"value": 60.0} == {"value": 60.0, "outcome": "failure",
                                                     "fails_at": "last_dom_topples", "overlap": None}
    for point in sweep["points"]:  # a slider set there gives what the sweep said
        before = fresh.state()["generation"]
        fresh.talk([{"type": "set", "name": "track.roll", "value": point["value"]}])
        s = fresh.wait(lambda s, b=before: s["generation"] > b and not s["busy"])
        assert s["main"]["outcome"] == point["outcome"], point
        assert s["main"]["fails_at"] == point["fails_at"]
    fresh.talk([{"type": "save", "name": "steep"}], until=lambda s: "saved" in s["notice"])
    saved = fresh.file.with_name("simple.layouts.json")
    code, out, _ = cli_output(["simulate", str(fresh.file), "--layout", str(saved), "--json"])
    assert json.loads(out)["values"] == {"track.x": -0.1, "track.z": 0.1, "track.roll": 75.0}
    assert fresh.file.read_text() == fresh.original  # never the scenario
    s = fresh.talk([{"type": "save", "name": "../x"}], until=lambda s: s["notice"])[-1]
    assert s["notice"].startswith("not saved: a layout's name")


def test_messages_the_server_does_not_take_change_nothing(fresh):
    before = fresh.state()
    bad = [{"type": "set", "name": ["track.x"], "value": 1}, {"type": "set", "name": "track.x",
           "value": True}, {"type": "set", "name": "track.x", "value": "1e999"},
           {"type": "set", "name": "nope", "value": 1}, {"type": "layout", "name": "/etc/passwd"},
           {"type": "compare", "name": {"a": 1}}, {"type": "sweep", "name": None}, [1, 2], "x",
           None, {"type": "save", "name": 7}, {}]
    states = fresh.talk(bad, until=lambda s: "{}" in s["notice"])  # the last one
    assert all(s["notice"].startswith("ignored a message") for s in states[1:])
    after = fresh.state()
    assert after["generation"] == before["generation"] and after["view"] == before["view"]


def test_every_open_page_gets_every_update(fresh):
    import asyncio

    import aiohttp

    async def two_pages():
        async with aiohttp.ClientSession() as session:
            a = await session.ws_connect(fresh.url + "ws")
            b = await session.ws_connect(fresh.url + "ws")
            start = [(await a.receive_json())["view"], (await b.receive_json())["view"]]
            await asyncio.to_thread(fresh.file.write_text, fresh.original.replace(TRACK, FAILING))
            seen = []
            for ws, view in zip((a, b), start, strict=True):
                s = await ws.receive_json(timeout=20)
                while s["view"] == view:
                    s = await ws.receive_json(timeout=20)
                seen.append(s["main"]["outcome"])
            await a.close()
            await b.close()
            return seen

    assert asyncio.run(two_pages()) == ["failure", "failure"]


@pytest.mark.slow  # 3-6 s: two workers started again
def test_a_comparison_and_a_dead_worker(fresh):
    s = fresh.talk([{"type": "compare", "name": "solved"},
                    {"type": "set", "name": "track.roll", "value": 60.0}],
                   until=lambda s: s.get("compare") and s["main"]["outcome"] == "failure")[-1]
    assert s["compare"]["outcome"] == "success" and s["compare_layout"] == "solved"
    fresh.talk([{"type": "compare", "name": None}, {"type": "layout", "name": "initial"}],
               until=lambda s: s["compare"] is None and not s["main"]["outcome"] == "failure")

    def worker_process():
        found = [p for p in psutil.Process(fresh.proc.pid).children()
                 if "resource_tracker" not in " ".join(p.cmdline())]
        assert len(found) == 1
        return found[0]

    worker_process().kill()  # idle: replaced without a word
    time.sleep(0.5)
    s = fresh.write(fresh.original)
    assert s["error"] is None and s["main"]["outcome"] == "success"
    fresh.talk([{"type": "sweep", "name": "track.x", "points": 201}],
               until=lambda s: len((s.get("sweep") or {}).get("points", [])) >= 3)
    worker_process().kill()  # while it works: one line says so
    s = fresh.wait(lambda s: s["sweep"]["done"])
    assert "the simulation worker stopped unexpectedly" in s["sweep"]["stopped"]
    s = fresh.write(fresh.original)
    assert s["error"] is None and s["main"]["outcome"] == "success"


@pytest.mark.slow  # 3-5 s: a server of its own
def test_a_saved_drawing_moves_the_run_that_follows_it(tmp_path):
    def drawing(length_mm):
        return ('<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" '
                f'viewBox="0 0 300 200"><path d="M 0 100 L {length_mm} 100"/></svg>')

    (tmp_path / "line.svg").write_text(drawing(100))
    scenario = tmp_path / "drawn.toml"
    scenario.write_text("""[objects.floor]\npart = "plane"\n[runs.run]
domino = { thickness = 0.005, width = 0.02, height = 0.04 }
path = { kind = "svg", file = "line.svg", spacing = 0.02 }\ntilt = 10\nmass = 0.03
free = { x = [-0.05, 0.05] }\n[events.falls]\ntype = "toppling"\nbody = "run[-1]"\nangle = 45
""")
    s = Server(tmp_path, scenario=scenario)
    try:
        def dominoes() -> int:
            status, page = _get(s, "/view")
            return page.decode().count('"name":"run[')

        assert dominoes() == 6
        before = s.state()["generation"]
        (tmp_path / "line.svg").write_text(drawing(200))
        s.wait(lambda state: state["generation"] > before and not state["busy"])
        assert dominoes() == 11
    finally:
        s.stop()


def test_a_port_in_use_or_a_bad_scenario_is_one_line_before_serving(tmp_path):
    with socket.create_server(("127.0.0.1", 0)) as taken:
        port = str(taken.getsockname()[1])
        code, _, err = cli_output(["live", "simple", "--no-browser", "--port", port])
    assert code == 2 and err.count("\n") == 1 and f"--port: {port}: in use" in err
    for text in ("", "[objects\n", "\x00\x01binary"):
        bad = tmp_path / "bad.toml"
        bad.write_text(text)
        code, out, err = cli_output(["live", str(bad), "--no-browser", "--port", "0"])
        assert code == 2 and out == "" and err.startswith("rgmcad: error: ") and err.count("\n") == 1
    code, _, err = cli_output(["live", "simple", "--port", "70000"])
    assert code == 2 and "argument --port" in err
    code, _, err = cli_output(["live", str(SIMPLE), "--layouts", str(SIMPLE)])
    assert code == 2 and "--layouts" in err


def test_ctrl_c_stops_the_server_and_its_worker(server):
    # the module's server, last: stopping it as its fixture would, and looking after it
    children = psutil.Process(server.proc.pid).children(recursive=True)
    assert children  # the worker (and multiprocessing's resource tracker)
    code, out, err = server.stop()
    assert code == 0 and out.splitlines()[-1] == "stopped", err
    gone, alive = psutil.wait_procs(children, timeout=5)
    assert not alive, [p.cmdline() for p in alive]


def test_ctrl_c_at_once_is_a_clean_stop_while_the_worker_still_starts(tmp_path):
    # a terminal's Ctrl-C goes to the whole process group: the worker, still importing, once
    # printed a KeyboardInterrupt traceback under the server's "stopped"
    proc = popen_as_terminal([sys.executable, "-m", "rgmcad.cli", "live", str(SIMPLE),
                              "--no-browser", "--port", "0"], cwd=tmp_path, text=True,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert "live page at" in proc.stdout.readline()
        children = psutil.Process(proc.pid).children(recursive=True)
        time.sleep(0.3)
        os.killpg(proc.pid, signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert proc.returncode == 0 and out.splitlines()[-1] == "stopped"
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
    _, alive = psutil.wait_procs(children, timeout=5)
    assert not [p for p in alive if p.status() != psutil.STATUS_ZOMBIE]


# --- pieces, in this process ----------------------------------------------------------------


class _Counter:
    """A generation counter that moves on after ``after`` looks (a newer request mid-run)."""

    def __init__(self, after: int):
        self.after, self.looks = after, 0

    @property
    def value(self) -> int:
        self.looks += 1
        return 0 if self.looks <= self.after else 99


def _request(**kw) -> worker.Request:
    from rgmcad.cli.paths import default_build_dir

    return worker.Request(str(SIMPLE), str(default_build_dir()), None, 0, 0, **kw)


def test_a_newer_request_stops_a_running_simulation(monkeypatch):
    counter = _Counter(after=3)
    monkeypatch.setitem(worker._state, "generation", counter)
    assert worker.view(_request()) == {"superseded": True}
    assert counter.looks == 4  # stopped in the run, at its third look
    monkeypatch.setitem(worker._state, "generation", _Counter(after=10**9))
    answer = worker.view(_request(changes=(("track.roll", 60.0),), compare="solved"))
    assert answer["main"]["outcome"] == "failure" and answer["compare"]["outcome"] == "success"
    assert answer["info"]["layout"] == "initial, track.roll=60"


def test_a_part_that_fails_to_build_or_a_simulation_that_raises_is_one_line(monkeypatch):
    from rgmcad.errors import PartBuildError

    monkeypatch.setitem(worker._state, "loaded", None)

    def cannot_build(*args):
        raise PartBuildError("track", "params", "the CAD build failed")

    monkeypatch.setattr("rgmcad.scene.bodies.load_parts", cannot_build)
    assert worker.view(_request()) == {"error": "rgmcad: error: track: params: the CAD build "
                                       "failed", "line": None}
    monkeypatch.undo()
    monkeypatch.setitem(worker._state, "loaded", None)

    def boom(*args, **kwargs):
        raise RuntimeError("pybullet said no\nat all")

    monkeypatch.setattr("rgmcad.viewer.recording.record_replay", boom)
    assert worker.view(_request())["error"] == ("rgmcad: error: the simulation failed: "
                                                "RuntimeError: pybullet said no at all")


def test_side_by_side_is_one_replay_with_one_clock():
    from rgmcad.scene.bodies import load_parts, make_scene
    from rgmcad.scene.design_space import values_from_mapping
    from rgmcad.scene.loader import load_scenario
    from rgmcad.sim.validity import check_validity
    from rgmcad.viewer.recording import record_replay, replay_payload
    from tests._support import PARTS

    scenario = load_scenario(SIMPLE)
    parts = load_parts(scenario, PARTS)
    values = values_from_mapping(scenario, scenario.layouts["initial"])
    _, a = record_replay(scenario, values, parts)
    _, b = record_replay(scenario, values + [0, 0, 30], parts)  # roll 60: runs longer
    both = side_by_side(a, b, ("A", "B"), "both")
    assert len(both.bodies) == len(a.bodies) + len(b.bodies) and len(both.times) == len(b.times)
    assert both.bodies[0] == f"A: {a.bodies[0]}" and both.events[-1]["name"].startswith("B: ")
    assert len(both.planes) == 1  # the floor, once
    assert both.labels[0] == f"A: {a.labels[0]}" and both.labels[-1] == "B: run"  # its tags
    np.testing.assert_array_equal(both.poses[-1, :len(a.bodies)], a.poses[-1])  # A holds
    moved = both.poses[0, len(a.bodies):, :3, 3] - b.poses[0, :, :3, 3]
    assert np.allclose(moved[:, 1:], 0) and np.all(moved[:, 0] > 0.1)  # B beside A, along x
    replay_payload(both)
    scene = make_scene(scenario, values * [1, 0, 1], parts)
    still = still_replay(scenario, scene, check_validity(scene), "invalid")
    red = [n for n, c in zip(still.bodies, still.colors, strict=True) if c[0] > 0.8 > c[1] + 0.5]
    assert red == ["track"] and still.outcome == "invalid" and len(still.times) == 1
    replay_payload(still)


def test_the_line_of_an_error_key():
    text = SIMPLE.read_text()
    lines = text.splitlines()
    for key, want in (("objects.track.free.x", "free = "), ("objects.track", "[objects.track]"),
                      ("simulation.duration", "duration = "), ("runs.run.path.count", "path = "),
                      ("events.last_dom_stops.max_linvel", "max_linvel"),
                      ("layouts.solved.track", "track = ")):
        assert lines[key_line(text, key) - 1].startswith(want), key
    assert key_line(text, "nowhere.at.all") is None


def test_the_watched_files_and_the_layout_file(tmp_path):
    drawing = tmp_path / "curve.svg"
    drawing.write_text("<svg/>")
    scenario = tmp_path / "s.toml"
    scenario.write_text('[runs.a]\npath = { kind = "svg", file = "curve.svg" }\n')
    assert watched_files(scenario) == {scenario.resolve(), drawing.resolve()}
    seen = []
    watcher = Watcher(seen.append)
    watcher.watch(watched_files(scenario))
    watcher.start()
    try:
        (tmp_path / "other.txt").write_text("x")
        scenario.read_text()
        time.sleep(0.3)
        assert seen == []
        drawing.write_text("<svg></svg>")
        deadline = time.monotonic() + 5
        while not seen and time.monotonic() < deadline:
            time.sleep(0.01)
        assert seen
    finally:
        watcher.stop()
    layouts = tmp_path / "s.layouts.json"
    write_saved(layouts, "one", {"values": {"a.x": 1.0}})
    assert write_saved(layouts, "two", {"values": {"a.x": 2.0}}) == {
        "one": {"values": {"a.x": 1.0}}, "two": {"values": {"a.x": 2.0}}}
    assert json.loads(layouts.read_text())["values"] == {"a.x": 2.0}
    assert set(read_saved(layouts)[0]) == {"one", "two"}
    notes = tmp_path / "notes.json"
    notes.write_text('{"anything": 1}')
    with pytest.raises(ValueError, match="not a layout file"):
        write_saved(notes, "x", {})
    assert notes.read_text() == '{"anything": 1}'
