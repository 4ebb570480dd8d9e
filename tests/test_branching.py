"""BRANCHING as Fig. 6 tells it: the ball gets to the goblet under the lever the second domino
run raises, and a lever that stays down stops it."""

import tomllib
from pathlib import Path

import numpy as np
from _support import PARTS

from rgmcad.scene.bodies import load_parts
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.loader import parse_scenario
from rgmcad.sim.run import Outcome, simulate

PATH = Path(__file__).parent.parent / "scenarios" / "branching.toml"


def _run(data, observer=None):
    sc = parse_scenario(data, where=str(PATH))
    values = values_from_mapping(sc, sc.layouts["solved"])
    return simulate(sc, values, load_parts(sc, PARTS), observer=observer, observe_every=5)


def test_the_ball_passes_under_the_raised_lever_into_the_goblet():
    data = tomllib.loads(PATH.read_text())
    seen = []

    def observe(world, t):
        lever = world.pose("lever")
        seen.append((world.pose("ball")[1, 3], lever[2, 0]))  # ball y, lever's +x end rising

    result = _run(data, observe)
    assert result.outcome is Outcome.SUCCESS
    lever_y = data["objects"]["lever"]["pose"]["y"]
    ball_y, rise = np.array(seen).T
    under = np.flatnonzero(ball_y > lever_y)[0]
    assert rise[under] > np.sin(np.radians(10))  # raised well before the ball gets there


def test_a_lever_that_stays_down_stops_the_ball():
    data = tomllib.loads(PATH.read_text())
    del data["objects"]["lever"]["mass"]  # static: run2 cannot raise it
    del data["events"]["lever_pivots"]
    data["events"]["ball_enters_goblet"]["after"] = ["ball_rolls_on_track"]
    result = _run(data)
    states = {e.name: e.state for e in result.events}
    assert result.outcome is Outcome.FAILURE
    assert states["ball_rolls_on_track"].value == "success"
    assert states["ball_enters_goblet"].value != "success"
