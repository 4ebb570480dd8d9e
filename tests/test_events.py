"""Every event type, in a tiny world where it must succeed and one where it must fail."""

import pytest
from _support import run, tiny

from rgmcad.eventspec import EVENT_TYPES

FLOOR = {"part": "plane"}
BALL = {"part": "ball", "params": {"radius": 0.01}, "mass": 0.01}
BLOCK = {"part": "box", "params": {"length": 0.05, "width": 0.05, "height": 0.02}}
CUP = {"part": "open_box", "params": {"length": 0.06, "width": 0.06, "height": 0.04,
                                      "wall": 0.003}}


def ball_at(z, **extra):
    return {**BALL, "pose": {"z": z, **extra.pop("pose", {})}, **extra}


# (objects, event) for a world where the event succeeds, then one where it fails
CASES = {
    "contact": (
        {"floor": FLOOR, "ball": ball_at(0.05)},
        {"type": "contact", "first": "ball", "second": "floor"},
        {"floor": {"part": "plane", "pose": {"z": -1}}, "ball": {**BALL, "pose": {"z": 0.5}}},
    ),
    "no_contact": (
        {"floor": FLOOR, "ball": ball_at(0.05)},
        {"type": "no_contact", "first": "ball", "second": "floor"},
        {"floor": FLOOR, "ball": ball_at(0.01)},
    ),
    "rolling_on": (
        {"ramp": {**BLOCK, "params": {"length": 1, "width": 0.1, "height": 0.02},
                  "pose": {"roll": -15}},
         "ball": {**BALL, "parent": "ramp", "pose": {"z": 0.02}}},
        {"type": "rolling_on", "rolling": "ball", "support": "ramp", "min_angvel": 5},
        {"floor": FLOOR, "ramp": {**BLOCK, "pose": {"z": 0.01}},
         "ball": ball_at(0.03)},  # resting on a flat block: touching but not spinning
    ),
    "pivoting": (
        {"lever": {"part": "lever", "params": {"length": 0.2, "width": 0.02, "thickness": 0.005,
                                              "pivot_x": 0.05},
                   "mass": 0.02, "pose": {"z": 0.2}}},
        {"type": "pivoting", "body": "lever", "min_angvel": 1},
        {"lever": {"part": "lever", "params": {"length": 0.2, "width": 0.02, "thickness": 0.005},
                   "mass": 0.02, "pose": {"z": 0.2}}},  # balanced on its axle
    ),
    "falling": (
        {"ball": ball_at(0.5)},
        {"type": "falling", "body": "ball", "min_linvel": 0.1},
        {"floor": FLOOR, "ball": ball_at(0.01)},
    ),
    "rising": (
        {"floor": {**FLOOR, "restitution": 0.9}, "ball": ball_at(0.03, restitution=0.9)},
        {"type": "rising", "body": "ball", "min_linvel": 0.1},
        {"ball": ball_at(0.5)},
    ),
    "stopping": (
        {"floor": FLOOR, "ball": ball_at(0.02)},
        {"type": "stopping", "body": "ball", "max_linvel": 0.01},
        {"ball": ball_at(0.5)},
    ),
    "not_moving": (
        {"floor": FLOOR, "ball": ball_at(0.01)},
        {"type": "not_moving", "body": "ball"},
        {"ball": ball_at(0.5)},
    ),
    "toppling": (
        {"floor": FLOOR, "slab": {**BLOCK, "params": {"length": 0.01, "width": 0.05,
                                                     "height": 0.1},
                                  "mass": 0.05, "pose": {"z": 0.05, "roll": 12}}},
        {"type": "toppling", "body": "slab", "angle": 30},
        {"floor": FLOOR, "slab": {**BLOCK, "mass": 0.05, "pose": {"z": 0.01}}},
    ),
    "inclusion": (
        {"floor": FLOOR, "cup": {**CUP, "pose": {"z": 0.02}}, "ball": ball_at(0.12)},
        {"type": "inclusion", "inside": "ball", "container": "cup"},
        {"floor": FLOOR, "cup": {**CUP, "pose": {"z": 0.02}},
         "ball": ball_at(0.01, pose={"x": 0.1})},
    ),
}


# Events about staying still are true at t = 0; their failing worlds wake them a little later,
# after a clock ball has started to fall.
DELAYED = {"stopping", "not_moving"}
CLOCK = {"part": "ball", "params": {"radius": 0.01}, "mass": 0.01, "pose": {"x": 1, "z": 1}}


def _events(event, delayed):
    if not delayed:
        return {"e": event}
    return {"start": {"type": "falling", "body": "clock", "min_linvel": 0.5},
            "e": {**event, "after": ["start"]}}


def test_every_event_type_has_cases():
    assert set(CASES) == set(EVENT_TYPES)


@pytest.mark.parametrize("kind", sorted(CASES))
def test_event_succeeds_where_it_must(kind):
    objects, event, _ = CASES[kind]
    result = run(tiny(objects, {"e": event}, duration=1.5, event_timeout=1.0))
    assert result.outcome.value == "success", result


@pytest.mark.parametrize("kind", sorted(CASES))
def test_event_fails_where_it_must(kind):
    _, event, objects = CASES[kind]
    delayed = kind in DELAYED
    if delayed:
        objects = {**objects, "clock": CLOCK}
    result = run(tiny(objects, _events(event, delayed), duration=1.5, event_timeout=0.5))
    assert result.outcome.value == "failure", result


@pytest.mark.parametrize("kind", ["falling", "contact", "toppling"])
def test_negated_event_succeeds_where_the_event_fails(kind):
    _, event, objects = CASES[kind]
    result = run(tiny(objects, {"e": {**event, "negate": True}}, duration=1.0,
                      event_timeout=0.3))
    assert result.outcome.value == "success"
