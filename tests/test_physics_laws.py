"""Physics against closed forms: free fall, rolling down an incline, a domino's tipping angle;
and a ball thrown into a cup stays in it."""

import math

import numpy as np
import pytest
from _support import scene_of, tiny

from rgmcad.geometry import invert
from rgmcad.sim.engine import Engine
from rgmcad.sim.world import World

G = 9.81
NEVER = {"e": {"type": "contact", "first": "ball", "second": "floor"}}


def test_free_fall_follows_half_g_t_squared():
    sc = tiny({"floor": {"part": "plane", "pose": {"z": -10}},
               "ball": {"part": "ball", "params": {"radius": 0.01}, "mass": 0.01,
                        "pose": {"z": 1.0}}}, NEVER)
    with World(scene_of(sc), sc.settings) as world:
        steps = 250
        for _ in range(steps):
            world.step()
        t = steps * sc.settings.timestep
        z = world.pose("ball")[2, 3]
        vz = world.velocity("ball")[0][2]
    # semi-implicit Euler lands within one step's worth of the exact parabola
    assert z == pytest.approx(1.0 - 0.5 * G * t**2, abs=G * t * sc.settings.timestep)
    assert vz == pytest.approx(-G * t, rel=1e-6)


@pytest.mark.parametrize("slope_deg", [10.0, 20.0])
def test_solid_ball_rolls_down_incline_at_five_sevenths_g_sin(slope_deg):
    # an inclined box as the ramp; the ball starts resting on it
    r = 0.01
    ramp_pose = {"roll": -slope_deg}  # positive roll lowers +X: -slope raises it, so the ball
    sc = tiny({"ramp": {"part": "box", "params": {"length": 2.0, "width": 0.2, "height": 0.02},
                        "pose": ramp_pose, "friction": 1.0},
               "ball": {"part": "ball", "params": {"radius": r}, "mass": 0.01, "friction": 1.0,
                        "parent": "ramp", "pose": {"x": 0.5, "z": 0.01 + r}}},
              {"e": {"type": "contact", "first": "ball", "second": "ramp"}})
    with World(scene_of(sc), sc.settings) as world:
        for _ in range(50):  # settle contact
            world.step()
        v0 = np.linalg.norm(world.velocity("ball")[0])
        steps = 200
        for _ in range(steps):
            world.step()
        v1 = np.linalg.norm(world.velocity("ball")[0])
    accel = (v1 - v0) / (steps * sc.settings.timestep)
    assert accel == pytest.approx(5 / 7 * G * math.sin(math.radians(slope_deg)), rel=0.03)


def _domino_falls(tilt_deg):
    t, h = 0.007, 0.044
    sc = tiny({"floor": {"part": "plane", "friction": 1.0}},
              {"e": {"type": "toppling", "body": "run[0]", "angle": 45}},
              runs={"run": {"domino": {"thickness": t, "width": 0.02, "height": h},
                            "path": {"kind": "line", "count": 1, "length": 0.0},
                            "tilt": tilt_deg, "mass": 0.003, "friction": 1.0}})
    with World(scene_of(sc), sc.settings) as world:
        for _ in range(600):
            world.step()
        up = world.pose("run[0]")[:3, 2]
    return math.degrees(math.acos(np.clip(up[2], -1, 1))) > 45


def test_domino_tips_past_atan_thickness_over_height():
    tipping = math.degrees(math.atan(0.007 / 0.044))  # 9.04 degrees
    assert not _domino_falls(tipping - 0.7)
    assert _domino_falls(tipping + 0.7)


GOBLET = {"inner_height": 0.11, "top_radius": 0.036, "bottom_radius": 0.025, "wall": 0.002}
RIM = GOBLET["inner_height"] + GOBLET["wall"]  # height of the rim in the goblet's frame
RIM_INNER_RADIUS = 0.034  # about: top_radius - wall / cos(wall's lean)


@pytest.mark.parametrize("tilt_deg", [0, 15])
def test_ball_thrown_into_a_goblet_stays_inside_whichever_wall_it_strikes(tilt_deg):
    # launched 2 cm above the middle of the rim, 0.3 m/s sideways: it strikes the wall, bounces
    # (restitution 0.8 x 0.5) and ends up at the bottom; 12 directions cover the whole wall
    sc = tiny({"goblet": {"part": "goblet", "params": GOBLET, "restitution": 0.5,
                          "pose": {"pitch": tilt_deg}},
               "ball": {"part": "ball", "params": {"radius": 0.008}, "mass": 0.0056,
                        "restitution": 0.8, "parent": "goblet", "pose": {"z": RIM + 0.02}}},
              {"e": {"type": "inclusion", "inside": "ball", "container": "goblet"}})
    scene = scene_of(sc)
    escaped = []
    with Engine() as engine:  # one engine, a fresh world in it per throw
        for k in range(12):
            with World(scene, sc.settings, engine) as world:
                a = math.radians(30 * k)
                world.engine.resetBaseVelocity(world.handles["ball"].uid,
                                               [0.3 * math.cos(a), 0.3 * math.sin(a), 0])
                for _ in range(500):  # 1 s
                    world.step()
                x, y, z, _ = invert(world.pose("goblet")) @ world.pose("ball")[:, 3]
            if not (math.hypot(x, y) < RIM_INNER_RADIUS and GOBLET["wall"] < z < RIM):
                escaped.append(f"{30 * k} deg: ball at r = {math.hypot(x, y):.3f} m, "
                               f"z = {z:.3f} m")
    assert not escaped
