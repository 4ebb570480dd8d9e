"""Every event type, in a tiny world where it must succeed and one where it must fail."""

import math

import numpy as np
import pytest
from _support import run, scene_of, tiny

from rgmcad.scene.bodies import load_parts
from rgmcad.scene.eventspec import EVENT_TYPES

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


# --- a point of the body: rising / falling with `end` or `point` ------------------------------

# A lever pivoted at its centre of mass (its centre never moves); a ball lands on its -x end
# at about 0.134 s, so the +x end rises and the -x end falls.
SEESAW = {"lever": {"part": "lever", "params": {"length": 0.2, "width": 0.02,
                                                "thickness": 0.005},
                    "mass": 0.02, "pose": {"z": 0.2}},
          "ball": {**BALL, "pose": {"x": -0.08, "z": 0.3}}}
IMPACT = 0.134


def _seesaw(event, timeout=1.0):
    return run(tiny(SEESAW, {"e": {"body": "lever", "min_linvel": 0.05, **event}},
                    duration=1.5, event_timeout=timeout))


def test_the_end_of_a_lever_pivoted_at_its_centre_rises():
    result = _seesaw({"type": "rising", "end": "+x"})
    assert result.outcome.value == "success"
    assert IMPACT <= result.events[0].time < IMPACT + 0.01
    result = _seesaw({"type": "falling", "end": "-x"})
    assert IMPACT <= result.events[0].time < IMPACT + 0.01


@pytest.mark.parametrize("kind", ["rising", "falling"])
def test_the_centre_of_a_lever_pivoted_at_its_centre_neither_rises_nor_falls(kind):
    assert _seesaw({"type": kind}).outcome.value == "failure"


def test_a_point_given_by_coordinates():
    result = _seesaw({"type": "rising", "point": {"x": 0.09, "z": 0.0025}}, timeout=0.25)
    assert result.outcome.value == "success"
    assert IMPACT <= result.events[0].time < IMPACT + 0.01
    # the -x side goes down after the impact: it does not rise within the timeout
    result = _seesaw({"type": "rising", "point": {"x": -0.09}}, timeout=0.25)
    assert result.outcome.value == "failure"


def test_end_is_the_centre_of_a_face_of_the_bounding_box():
    from rgmcad.sim.events import end_point

    scenario = tiny(SEESAW, {"e": {"type": "rising", "body": "lever", "end": "+x"}})
    built = load_parts(scenario)["lever"].bodies[""]
    assert np.allclose(end_point(built, "+x"), [0.1, 0, 0], atol=1e-6)
    assert np.allclose(end_point(built, "-z"), [0, 0, -0.0025], atol=1e-6)


def test_point_velocity_is_the_rate_of_change_of_the_point_position():
    """v_com + omega x (p - p_com), against finite differences, on a hinged lever swinging
    under gravity (a multibody link) and a slab tipping over (a free base body)."""
    from rgmcad.sim.events import point_velocity_reader
    from rgmcad.sim.world import World

    objects = {
        "floor": FLOOR,
        "lever": {"part": "lever", "params": {"length": 0.2, "width": 0.02, "thickness": 0.005,
                                              "pivot_x": 0.03},
                  "mass": 0.02, "pose": {"z": 0.2}},
        "slab": {**BLOCK, "params": {"length": 0.01, "width": 0.05, "height": 0.1},
                 "mass": 0.05, "pose": {"x": 0.5, "z": 0.06, "roll": 20, "heading": 30}},
    }
    scenario = tiny(objects, {"e": {"type": "rising", "body": "lever"}})
    with World(scene_of(scenario), scenario.settings) as world:
        dt = scenario.settings.timestep
        points = {"lever": (0.1, 0.01, 0.0025), "slab": (0.005, 0.02, 0.05)}
        readers = {b: (point_velocity_reader(world, b, p), world.point_reader(b, p))
                   for b, p in points.items()}
        checked = 0
        for i in range(1, 61):
            before = {b: (np.array(v()), np.array(p())) for b, (v, p) in readers.items()}
            world.step()
            if i % 20:
                continue
            for body, (velocity, position) in readers.items():
                v0, p0 = before[body]
                v1 = np.array(velocity())
                moved = (np.array(position()) - p0) / dt
                # the engine moves the point with about the velocity before or after the step
                error = min(np.linalg.norm(moved - v0), np.linalg.norm(moved - v1))
                assert error <= 0.02 * np.linalg.norm(v1) + 1e-3, (body, i, moved, v0, v1)
                assert np.linalg.norm(v1) > 0.05  # moving: the check means something
                checked += 1
    assert checked == 6


def test_a_hinged_lever_is_judged_on_the_pose_of_the_step():
    """A lever swinging on its axle (a multibody link): its toppling event fires at the step
    after which its true angle (the joint's coordinate) first reaches the threshold, and the
    readers give the attitude and the centre's velocity of that step, not the step before's."""
    import pybullet as pb

    from rgmcad.sim.world import World

    lever = {"part": "lever", "params": {"length": 0.2, "width": 0.02, "thickness": 0.005,
                                         "pivot_x": 0.05}, "mass": 0.02, "pose": {"z": 0.3}}
    scenario = tiny({"lever": lever}, {"e": {"type": "toppling", "body": "lever", "angle": 20}})
    with World(scene_of(scenario), scenario.settings) as world:
        h = world.handles["lever"]
        frame, velocity = world.frame_reader("lever"), world.velocity_reader("lever")
        start = np.array(pb.getQuaternionFromEuler([0, 0, 0]))
        steps, angle = 0, 0.0
        while angle < math.radians(20):
            world.step()
            steps += 1
            angle = abs(pb.getJointState(h.uid, h.link, physicsClientId=world.cid)[0])
            position, quaternion = frame()
            turned = 2 * math.acos(min(1.0, abs(float(np.dot(quaternion, start)))))
            assert turned == pytest.approx(angle, abs=1e-9), steps
            axis_point = np.asarray(world.scene.hinges[0].point, float)  # fixed in the world
            omega = np.array(velocity()[1])
            wanted = np.cross(omega, np.array(position) - axis_point)
            assert np.allclose(velocity()[0], wanted, atol=1e-9), steps
    result = run(scenario)
    assert result.events[0].time == pytest.approx(steps * scenario.settings.timestep, abs=1e-12)


# --- negate = "always": the condition never holds while the event is awake ------------------

DROP = {"floor": FLOOR, "ball": ball_at(0.2)}  # touches the floor at about 0.197 s
CONTACT = {"type": "contact", "first": "ball", "second": "floor"}


def test_negate_always_succeeds_at_the_timeout_when_the_condition_never_holds():
    objects = {"floor": {**FLOOR, "pose": {"z": -1}}, "ball": ball_at(0.5)}
    result = run(tiny(objects, {"e": {**CONTACT, "negate": "always", "timeout": 0.3}},
                      duration=1.0))
    assert result.outcome.value == "success"
    assert 0.3 < result.events[0].time <= 0.3 + 0.002 + 1e-9
    assert result.sim_time == result.events[0].time  # the run stops there


def test_negate_always_fails_at_the_step_the_condition_first_holds():
    plain = run(tiny(DROP, {"e": CONTACT}, duration=1.0))
    touched = plain.events[0].time
    assert plain.outcome.value == "success" and 0.18 < touched < 0.21
    never = run(tiny(DROP, {"e": {**CONTACT, "negate": "always", "timeout": 0.5}},
                     duration=1.0))
    assert never.outcome.value == "failure"
    assert never.events[0].state == "failure" and never.events[0].time == touched


def test_negate_true_still_means_false_at_some_time_within_the_timeout():
    # the ball touches the floor later, but it does not at t = 0: negate = true succeeds there
    result = run(tiny(DROP, {"e": {**CONTACT, "negate": True, "timeout": 0.5}}, duration=1.0))
    assert result.outcome.value == "success" and result.events[0].time == 0.0


def test_negate_always_wakes_its_children_at_the_timeout():
    objects = {"floor": {**FLOOR, "pose": {"z": -1}}, "ball": ball_at(0.5)}
    events = {"quiet": {**CONTACT, "negate": "always", "timeout": 0.2},
              "falls": {"type": "falling", "body": "ball", "min_linvel": 0.1,
                        "after": ["quiet"]}}
    result = run(tiny(objects, events, duration=1.0))
    assert result.outcome.value == "success"
    assert result.events[0].time == result.events[1].time


def test_every_event_type_a_scenario_may_name_has_a_condition_and_no_other():
    from rgmcad.scene.eventspec import EVENT_TYPES
    from rgmcad.sim.events import EVENTS

    assert set(EVENTS) == set(EVENT_TYPES)


@pytest.mark.parametrize(("offset", "outcome"), [(0.0, "success"), (0.05, "failure")])
def test_inclusion_in_a_free_turned_cup(offset, outcome):
    """A cup that can move (it has a mass), turned and away from the origin: a ball dropped
    on its centre ends inside it, one dropped 5 cm off its centre along the cup's own x axis
    lands beside it."""
    heading = math.radians(30)
    cup = {**CUP, "mass": 0.05, "pose": {"x": 0.2, "y": 0.1, "z": 0.02, "heading": 30}}
    ball = ball_at(0.12, pose={"x": 0.2 + offset * math.cos(heading),
                               "y": 0.1 + offset * math.sin(heading)})
    event = {"type": "inclusion", "inside": "ball", "container": "cup"}
    result = run(tiny({"floor": FLOOR, "cup": cup, "ball": ball}, {"e": event}, duration=1.5,
                      event_timeout=1.0))
    assert result.outcome.value == outcome, result
