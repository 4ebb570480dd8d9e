"""Assembly steps follow the template's placement order: every part is placed exactly once
and never before a part it rests on, a domino run is one step, a rope comes after the parts
it is tied to, a support before the part it holds; each step has a picture of the machine so
far, and the template's PDF has the steps' pages."""

from __future__ import annotations

import math

import numpy as np
import pytest
from test_bom import generated, made_template, pdf_text, shipped

from rgmcad.making.steps import (
    Support,
    assembly_steps,
    placement_order,
    render_steps,
    rests_on,
)
from rgmcad.shipped import shipped_scenarios

CASES = [("shipped", name) for name in sorted(shipped_scenarios())] + [
    ("generated", seed) for seed in range(6)]


def _scene(kind, which):
    return shipped(which) if kind == "shipped" else generated(which)


def follow(scenario, scene, steps, supports=()):
    """Walk the steps in order as a builder does, checking each against what is placed."""
    below = rests_on(scene)
    placed: list[str] = []
    objects: set[str] = set()
    stood: set[str] = set()
    holds = {s.name: s.holds for s in supports}
    for k, step in enumerate(steps, start=1):
        assert step.number == k
        if step.kind == "support":
            assert holds[step.support] not in placed  # before the part it holds
            stood.add(step.support)
        for name in step.bodies:
            assert name not in placed, f"{name} placed twice"
            missing = [b for b in below[name] if b not in placed and b not in step.bodies]
            assert not missing, f"step {k}: {name} before {missing}, which it rests on"
            assert all(s in stood for s, h in holds.items() if h == name)
        placed += step.bodies
        objects.update(scene.bodies[b].object for b in step.bodies)
        if step.kind == "rope":
            rope = next(r for r in scene.ropes if r.name == step.rope)
            assert {o for o in rope.objects if o in scene.bodies} <= objects
    return placed


@pytest.mark.parametrize("kind, which", CASES)
def test_every_part_is_placed_once_never_before_what_it_rests_on(kind, which):
    scenario, scene = _scene(kind, which)
    steps = assembly_steps(scenario, scene)
    placed = follow(scenario, scene, steps)
    order = placement_order(scenario, scene)
    assert sorted(placed) == sorted(order)  # every part, once
    assert sorted(s.rope for s in steps if s.kind == "rope") == sorted(
        r.name for r in scene.ropes)
    number = {name: k + 1 for k, name in enumerate(order)}
    for step in steps:  # the template's numbers
        assert step.orders == tuple(number[b] for b in step.bodies)
    runs = [s for s in steps if s.kind == "run"]
    assert len(runs) == len(scenario.runs)  # a run is one step
    for step in runs:
        assert sorted(scene.bodies[b].object for b in step.bodies) == sorted(
            scenario.runs[step.text.split("run ")[1].split(",")[0]])
    single = [s.orders[0] for s in steps if s.kind == "part"]
    assert single == sorted(single)  # the other parts in the template's order


def test_a_support_comes_right_before_the_part_it_holds():
    scenario, scene = shipped("ballrun")
    supports = [Support("stand_a", "top_track"), Support("stand_b", "bottom_track")]
    steps = assembly_steps(scenario, scene, supports)
    follow(scenario, scene, steps, supports)
    for s in supports:
        k = next(i for i, step in enumerate(steps) if step.support == s.name)
        assert steps[k + 1].bodies == (s.holds,)


def _stand(label: str, part: str, x: float):
    from rgmcad.making.stands import Stand

    frame = np.eye(4)
    frame[:3, 3] = (x, 0.0, 0.0)
    return Stand(label, part, "floor", frame,
                 np.array([[0.0, 0.0], [0.03, 0.0], [0.03, 0.02], [0.0, 0.02]]),
                 np.array([0.0, 0.0, 0.05]))


def test_stands_are_a_line_of_the_bill_and_a_step_with_a_picture():
    from rgmcad.making.bom import bill_of_materials, support_lines
    from rgmcad.making.steps import supports_of

    scenario, scene = shipped("ballrun")
    stands = [_stand("S1", "top_track", -0.1), _stand("S2", "bottom_track", 0.1)]
    bill = bill_of_materials(scenario, scene, supports=support_lines(stands))
    assert [line.parts for line in bill.of("support")] == [("S1",), ("S2",)]
    assert bill.of("support")[0].what == "stand S1, 30 x 20 mm, 50 mm high"
    steps = assembly_steps(scenario, scene, supports_of(stands))
    follow(scenario, scene, steps, supports_of(stands))
    first = next(s for s in steps if s.support == "S1")
    assert first.orders == (1,) and "Stand the support 1. S1" in first.text
    assert min(o for s in steps for o in s.orders if s.bodies) == 3  # the stands are 1 and 2
    k = steps.index(first)
    pictures = render_steps(scenario, scene, steps, width=96, height=72, stands=stands)
    orange = [int(np.sum((p[:, :, 0] > 180) & (p[:, :, 2] < 80))) for p in pictures]
    assert orange[k] > 0


def test_the_steps_number_parts_and_stands_as_the_template_does():
    from rgmcad.making.steps import supports_of
    from rgmcad.printing.inputs import template_inputs, with_supports

    scenario, scene = shipped("ballrun")
    stands = [_stand("S1", "top_track", -0.1), _stand("S2", "bottom_track", 0.1)]
    drawn = {p.name: p.order for p in with_supports(template_inputs(scenario, scene)[0], stands)}
    for step in assembly_steps(scenario, scene, supports_of(stands)):
        names = step.bodies or [n for n in drawn if n.startswith(f"{step.support} ")]
        assert step.orders == tuple(drawn[n] for n in names)


def test_the_ball_rests_on_its_track_and_comes_after_it():
    scenario, scene = shipped("ballrun")
    assert "top_track" in rests_on(scene)["ball"]
    steps = assembly_steps(scenario, scene)
    last = steps[-1]
    assert last.bodies == ("ball",) and "on 6. top_track" in last.text


def test_each_picture_shows_the_machine_so_far():
    scenario, scene = shipped("ballrun")
    steps = assembly_steps(scenario, scene)
    pictures = render_steps(scenario, scene, steps, width=96, height=72)
    assert len(pictures) == len(steps) and pictures[0].shape == (72, 96, 3)
    orange = [int(np.sum((p[:, :, 0] > 180) & (p[:, :, 2] < 80))) for p in pictures]
    # what each step places shows in orange (the lever's 5 mm axle is under a pixel here)
    assert all(n > 0 for n, s in zip(orange, steps, strict=True) if s.bodies != ("base_plank.axle",))
    background = pictures[0][0, 0]
    drawn = [int(np.any(p != background, axis=2).sum()) for p in pictures]
    assert drawn[0] < drawn[-1]


def test_the_pdf_has_the_steps_pages():
    folder, data = made_template()
    steps = data["steps"]
    pages = [t for t in pdf_text(folder) if "assembly steps" in t]
    assert len(pages) == math.ceil(len(steps) / 6)
    joined = " ".join(" ".join(pages).split())
    for s in steps:
        assert " ".join(s["text"].split()[:4]) in joined


def test_the_report_reads_the_stands_of_a_run_and_skips_a_malformed_file(caplog):
    from rgmcad.viewer.making import stands_of

    stand = _stand("S1", "top_track", -0.1)
    (read,) = stands_of({"stands": [stand.to_json()]})
    assert read.label == "S1" and np.allclose(read.vertices(), stand.vertices())
    assert stands_of(None) == [] and stands_of({"stands": [{"label": "S1"}]}) == []
    assert "supports.json" in caplog.text
