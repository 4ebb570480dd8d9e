"""The bill of materials counts every part of a layout once, on one line of its kind (balls
by diameter and simulated mass, dominoes by size, printed and cut parts, ropes by length),
for the shipped scenarios and for scenarios generated from a seed; the template's PDF holds
it, and ``rgmcad template --bom-json`` prints it."""

from __future__ import annotations

import atexit
import functools
import json
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pypdfium2 as pdfium
import pytest
from _support import PARTS, cli_output

from rgmcad.making.bom import KINDS, PaperUse, bill_of_materials
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario, parse_scenario
from rgmcad.shipped import shipped_scenarios

PART_KINDS = ("ball", "domino", "printed", "cut")
DOMINO = {"thickness": 0.007, "width": 0.02, "height": 0.044}  # parts the suite has built


def generated(seed: int):
    """A scenario with a random number of balls, blocks (one stacked on another), dominoes
    in a run and ropes, of parts the shipped scenarios already built."""
    rng = np.random.default_rng(seed)
    objects = {"floor": {"part": "plane"}}
    for i in range(int(rng.integers(1, 4))):
        objects[f"ball{i}"] = {"part": "ball", "params": {"radius": 0.01},
                               "mass": float(rng.choice([0.005, 0.01, 0.02])),
                               "pose": {"x": 0.05 * i, "y": 0.2, "z": 0.01}}
    for i in range(int(rng.integers(1, 4))):
        objects[f"block{i}"] = {"part": "box", "params": {"length": 0.02, "width": 0.044,
                                                          "height": 0.007},
                                "pose": {"x": 0.05 * i, "y": -0.2, "z": 0.0035}}
    objects["on_block0"] = {"part": "box", "params": {"length": 0.02, "width": 0.044,
                                                      "height": 0.007},
                            "parent": "block0", "pose": {"z": 0.007}}
    objects["plank"] = {"part": "box", "params": {"length": 0.008, "width": 0.024,
                                                  "height": 0.118}, "mass": 0.01,
                        "pose": {"x": -0.2, "z": 0.059}}
    count = int(rng.integers(2, 9))
    runs = {"run": {"domino": DOMINO, "mass": 0.00305, "pose": {"x": 0.2},
                    "path": {"kind": "line", "count": count, "length": 0.03 * (count - 1)}}}
    ropes = {f"rope{i}": {"ends": [{"object": f"ball{i}"}, {"point": [0.05 * i, 0.2, 0.3]}],
                          "length": float(rng.uniform(0.3, 0.5))}
             for i in range(int(rng.integers(0, 2)))}
    data = {"name": f"generated{seed}", "objects": objects, "runs": runs, "ropes": ropes,
            "events": {"e": {"type": "stopping", "body": "ball0"}}}
    scenario = parse_scenario(data, where="<generated>")
    values = values_from_mapping(scenario, scenario.layouts["initial"])
    return scenario, make_scene(scenario, values, load_parts(scenario, PARTS))


def shipped(name: str):
    scenario = load_scenario(shipped_scenarios()[name])
    _, values = resolve_layout(scenario, "solved" if "solved" in scenario.layouts
                               else next(iter(scenario.layouts)), None)
    return scenario, make_scene(scenario, values, load_parts(scenario, PARTS))


def check_counts(scenario, scene, bill):
    """Every object with a body on one part line, once; every rope once; counts add up."""
    objects = [o.name for o in scenario.body_objects()
               if o.name in scene.bodies and not scene.bodies[o.name].plane]
    counted = [p for line in bill.lines if line.kind in PART_KINDS for p in line.parts]
    assert sorted(counted) == sorted(objects)
    for line in bill.lines:
        assert line.count == len(line.parts) or line.kind in ("paper", "tape")
        assert line.kind in KINDS and line.count > 0
    assert sorted(p for line in bill.of("rope") for p in line.parts) == sorted(
        r.name for r in scene.ropes)
    dominoes = {n for names in scenario.runs.values() for n in names}
    assert sum(line.count for line in bill.of("domino")) == len(dominoes)
    for line in bill.of("ball") + bill.of("domino"):  # the mass the simulation assumed
        for name in line.parts:
            assert line.mass_g == pytest.approx(scene.bodies[name].mass * 1000.0, abs=0.051)


@pytest.mark.parametrize("name", sorted(shipped_scenarios()))
def test_bill_counts_every_part_of_a_shipped_layout_once(name):
    scenario, scene = shipped(name)
    check_counts(scenario, scene, bill_of_materials(scenario, scene))


@pytest.mark.parametrize("seed", range(6))
def test_bill_counts_every_part_of_a_generated_scenario_once(seed):
    scenario, scene = generated(seed)
    bill = bill_of_materials(scenario, scene, paper=PaperUse("a4", 5, 3, 2, 6))
    check_counts(scenario, scene, bill)
    balls = [o for o in scenario.objects.values() if o.part == "ball"]
    assert sum(line.count for line in bill.of("ball")) == len(balls)
    assert bill.of("ball")[0].size_mm == (20.0,)  # diameter
    assert [line.count for line in bill.of("paper")] == [5]
    assert [line.count for line in bill.of("tape")] == [6 + 4]  # marks and corners


def test_balls_of_one_size_and_mass_share_a_line():
    scenario, scene = generated(3)
    bill = bill_of_materials(scenario, scene)
    keys = [(line.size_mm, line.mass_g) for line in bill.of("ball")]
    assert len(keys) == len(set(keys))


@functools.cache
def made_template():
    """``(folder, JSON of --bom-json)`` of ballrun's solved layout's template, made once per
    process for this module and tests/test_assembly_steps.py (removed at exit)."""
    folder = Path(tempfile.mkdtemp(prefix="rgmcad-bom-test-"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    code, out, err = cli_output(["template", "ballrun", "--layout", "solved", "--out",
                                 str(folder), "--bom-json"])
    assert code == 0, err
    return folder, json.loads(out)


def pdf_text(folder) -> list[str]:
    doc = pdfium.PdfDocument(str(folder / "template.pdf"))
    try:
        return [doc[i].get_textpage().get_text_range() for i in range(len(doc))]
    finally:
        doc.close()


def test_bom_json_parses_and_the_pdf_has_its_page():
    folder, data = made_template()
    assert data["scenario"] == "ballrun" and data["layout"] == "solved"
    kinds = {line["kind"] for line in data["lines"]}
    assert {"ball", "printed", "cut", "paper", "tape"} <= kinds
    text = pdf_text(folder)
    assert [line["count"] for line in data["lines"] if line["kind"] == "paper"] == [len(text)]
    bom = [i for i, t in enumerate(text) if "bill of materials" in t]
    assert len(bom) == 1 and "16 mm across" in text[bom[0]]
    assert all((folder / f).is_file() for line in data["lines"] for f in line["files"])


@pytest.mark.parametrize("argv, word", [
    (["template", "nope", "--layout", "solved", "--out", "x", "--bom-json"], "nope"),
    (["template", "ballrun", "--layout", "nope", "--out", "x", "--bom-json"], "nope"),
])
def test_bad_input_gives_one_line_and_status_2(tmp_path, monkeypatch, argv, word):
    monkeypatch.chdir(tmp_path)
    code, out, err = cli_output(argv)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and word in err
