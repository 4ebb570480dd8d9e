"""`rgmcad template` and `rgmcad verify-print` on the shipped scenarios, end to end."""

import contextlib
import io
import json
from pathlib import Path

import numpy as np
import pypdfium2 as pdfium
import pytest
from PIL import Image

from rgmcad.cli import main
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario

DPI = 300
KEYS = {"pdf", "svg", "plane", "paper", "orientation", "sheets", "parts"}


def _template(tmp, scenario, *extra):
    out = tmp / Path(scenario).stem
    return out, ["template", f"scenarios/{scenario}.toml", "--out", str(out), "--json", *extra]


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """The JSON of `rgmcad template --layout solved --json` for ballrun and causality_switch."""
    tmp = tmp_path_factory.mktemp("cli_print")
    out = {}
    for name in ("ballrun", "causality_switch"):
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(_template(tmp, name, "--layout", "solved")[1]) == 0
        out[name] = json.loads(buf.getvalue())
    return out


def _bodies(name):
    scenario = load_scenario(f"scenarios/{name}.toml")
    _, values = resolve_layout(scenario, "solved", None)
    return scenario, make_scene(scenario, values, load_parts(scenario)).bodies


@pytest.mark.parametrize("name, plane", [("ballrun", "board"), ("causality_switch", "floor")])
def test_template_writes_files_and_reports_them(made, name, plane):
    out = made[name]
    assert KEYS <= set(out)
    assert Path(out["pdf"]).stat().st_size > 0 and Path(out["svg"]).stat().st_size > 0
    assert out["plane"] == plane  # chosen automatically: the plane the parts stand on
    assert out["paper"] == "a4" and out["orientation"] in ("portrait", "landscape")
    assert len(out["sheets"]) >= 2 and out["sheets"][0] == "A1"
    assert len(pdfium.PdfDocument(out["pdf"])) == out["pages"] >= len(out["sheets"]) + 1
    _, bodies = _bodies(name)
    solid = [b for b in bodies.values() if not b.plane]
    assert len(out["parts"]) == len(solid)
    assert {p["name"] for p in out["parts"]} == {b.name for b in solid}
    assert sorted(p["order"] for p in out["parts"]) == list(range(1, len(solid) + 1))
    for p in out["parts"]:
        assert {"name", "order", "centroid_world"} <= set(p) and len(p["centroid_world"]) == 3


@pytest.mark.parametrize("name, last", [("ballrun", "ball"), ("causality_switch", "branch_run[0]")])
def test_placement_order_supports_first_trigger_last(made, name, last):
    _, bodies = _bodies(name)
    order = {p["name"]: p["order"] for p in made[name]["parts"]}
    static = [order[n] for n, b in bodies.items() if not b.plane and b.static]
    moving = [order[n] for n, b in bodies.items() if not b.plane and not b.static]
    assert max(static) < min(moving)
    assert order[last] == len(order)  # the part that starts the chain goes in last
    if name == "ballrun":
        assert "base_plank.axle" in order and order["base_plank.axle"] < order["base_plank"]
        assert order["base_plank"] < order["high_plank"]  # the plank rests on the lever


def test_human_summary(tmp_path, capsys):
    out, argv = _template(tmp_path, "ballrun", "--layout", "solved")
    assert main([a for a in argv if a != "--json"]) == 0
    text = capsys.readouterr().out
    assert "board plane" in text and "sheets" in text and "a4" in text
    assert str(out / "template.pdf") in text and str(out / "template.svg") in text


def test_paper_auto_needs_no_more_sheets(made, tmp_path, capsys):
    _, argv = _template(tmp_path, "ballrun", "--layout", "solved", "--paper", "auto")
    assert main(argv) == 0
    auto = json.loads(capsys.readouterr().out)
    assert len(auto["sheets"]) <= len(made["ballrun"]["sheets"])


def test_tolerances_from_a_layout_file_are_printed(tmp_path, capsys):
    scenario = load_scenario("scenarios/ballrun.toml")
    layout = tmp_path / "robust.json"
    layout.write_text(json.dumps({
        "scenario": "ballrun", "values": scenario.layouts["solved"],
        "tolerances": {"top_track.x": [0.003, 0.003], "goblet.roll": [1.0, 2.0],
                       "bottom_track_joint.z": [0.002, 0.004]},
    }))
    out, argv = _template(tmp_path, "ballrun", "--layout", str(layout))
    assert main(argv) == 0
    made = json.loads(capsys.readouterr().out)
    parts = {p["name"]: p["notes"] for p in made["parts"]}
    assert parts["top_track"] == ["x ± 3 mm"]
    assert parts["goblet"] == ["roll -1/+2°"]
    # a frame's parameter is stated once, at the frame, not beside each of its parts
    assert parts["bottom_track"] == [] and parts["ball"] == []
    frames = {f["name"]: f["notes"] for f in made["frames"]}
    assert frames == {"bottom_track_joint": ["z -2/+4 mm"]}
    # and as numbers, the mapping the layout file gave (docs/how-to/print.md: `tolerances`)
    numbers = {p["name"]: p["tolerances"] for p in made["parts"]}
    assert numbers["top_track"] == {"top_track.x": [0.003, 0.003]}
    assert numbers["goblet"] == {"goblet.roll": [1.0, 2.0]} and numbers["ball"] == {}
    assert {f["name"]: f["tolerances"] for f in made["frames"]} == {
        "bottom_track_joint": {"bottom_track_joint.z": [0.002, 0.004]}}
    svg = (out / "template.svg").read_text(encoding="utf-8")
    assert "x ± 3 mm" in svg and "roll -1/+2°" in svg and "z -2/+4 mm" in svg


def _raster(pdf, index, path):
    doc = pdfium.PdfDocument(str(pdf))
    doc[index].render(scale=DPI / 72).to_pil().convert("L").save(path, dpi=(DPI, DPI))
    doc.close()
    return str(path)


@pytest.mark.parametrize("name", ["ballrun", "causality_switch"])
def test_verify_print_on_a_rasterised_sheet(made, name, tmp_path, capsys):
    out = made[name]
    last = _raster(out["pdf"], out["pages"] - 1, tmp_path / "sheet.png")  # the last tiled sheet
    assert main(["verify-print", last, "--json"]) == 0
    check = json.loads(capsys.readouterr().out)
    assert {"sheet", "scale_error_percent", "scale", "method", "message"} <= set(check)
    assert check["sheet"] == out["sheets"][-1]
    assert abs(check["scale_error_percent"]) < 0.3 and check["method"] == "dpi"
    assert check["ok"] is True
    first = _raster(out["pdf"], 0, tmp_path / "map.png")
    assert main(["verify-print", first]) == 0
    text = capsys.readouterr().out
    assert "sheet map" in text and "scale OK" in text


def _one_line_exit_2(argv, capsys, *needles):
    assert main(argv) == 2
    captured = capsys.readouterr()
    err = captured.err.strip()
    assert len(err.splitlines()) == 1 and captured.out == ""
    for n in needles:
        assert n in err
    return err


def test_bad_input_gives_one_line_and_exit_2(tmp_path, capsys):
    _, argv = _template(tmp_path, "ballrun", "--layout", "nonexistent")
    _one_line_exit_2(argv, capsys, "nonexistent")
    other = tmp_path / "other.json"
    other.write_text(json.dumps({"scenario": "simple", "vector": [0.5] * 3}))
    _, argv = _template(tmp_path, "ballrun", "--layout", str(other))
    _one_line_exit_2(argv, capsys, "simple")
    _, argv = _template(tmp_path, "ballrun", "--layout", "solved", "--plane", "floor")
    _one_line_exit_2(argv, capsys, "floor")  # ballrun has a board, no floor
    bad_tol = tmp_path / "bad_tol.json"
    bad_tol.write_text(json.dumps({"scenario": "ballrun", "vector": [0.5] * 8,
                                   "tolerances": {"top_track.size": [0.001, 0.001]}}))
    _, argv = _template(tmp_path, "ballrun", "--layout", str(bad_tol))
    _one_line_exit_2(argv, capsys, "tolerances.top_track.size")

    garbage = tmp_path / "photo.png"
    garbage.write_bytes(b"not an image at all")
    _one_line_exit_2(["verify-print", str(garbage)], capsys, str(garbage))
    _one_line_exit_2(["verify-print", str(tmp_path / "missing.jpg")], capsys, "missing.jpg")
    blank = tmp_path / "blank.png"
    rng = np.random.default_rng(0)
    Image.fromarray((200 + rng.integers(0, 40, (600, 400))).astype(np.uint8)).save(blank)
    _one_line_exit_2(["verify-print", str(blank), "--json"], capsys, "no template marks")


def test_a_sheet_with_nothing_to_place_says_so_and_the_others_do_not(tmp_path):
    # teapot's drawing is wide and sparse: some of its sheets show no part; a maker reading
    # the parts list ("[sheet C2, D2]") finds each part's sheets, and an empty one says why
    # it is there
    import re

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["template", "teapot", "--layout", "solved", "--out", str(tmp_path)]) == 0
    doc = pdfium.PdfDocument(str(tmp_path / "template.pdf"))
    texts = [doc[i].get_textpage().get_text_range() for i in range(len(doc))]
    sheets = {re.search(r"sheet (\w+) of \d+ x \d+", t).group(1): t for t in texts
              if re.search(r"sheet (\w+) of \d+ x \d+", t)}
    listed = set()
    for t in texts[: len(texts) - len(sheets)]:  # the map and the parts list
        for group in re.findall(r"\[sheets? ([^\]]*)\]", t.replace("\r\n", " ")):
            listed.update(x.strip() for x in group.split(","))
    empty = {label for label, t in sheets.items() if "Nothing to place on this sheet" in t}
    assert empty and empty == set(sheets) - listed
    said = next(ln for ln in out.getvalue().splitlines() if "hold nothing to place" in ln)
    assert said.startswith(f"{len(empty)} of {len(sheets)} sheets")
    assert all(label in said for label in empty)
