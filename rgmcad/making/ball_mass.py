"""How far off a ball's mass may be before the built-by-hand figure drops, by simulation.

The balls of a layout (objects of the ``ball`` family that move) are given their simulated
mass times each of :data:`FACTORS`, and the layout is built ``samples`` times at each mass
under the same hand's and physical errors (the first draws of the headline rate,
:func:`rgmcad.runs.hand.measure_rate`, the same draws at every mass: common random numbers,
so the rates differ by the mass alone). A mass drops the figure where its rate is more than
:data:`DROP` below the rate at the simulated mass and the draws it lost outnumber those it
gained beyond chance (a one-sided sign test at 5 % on the paired draws); the range kept is
the run of masses around the simulated one that do not.

It costs ``samples * len(FACTORS)`` simulations, so it is measured once for a run's layout
and kept beside it (:data:`CACHE_FILE`, keyed by the scenario file's digest and the layout's
values), never at every template: ``tools/ball_mass.py``.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

FACTORS = (0.5, 0.75, 0.9, 1.0, 1.1, 1.25, 1.5, 2.0)
"""Masses tried, as factors of the simulated mass."""
DROP = 0.05
"""A rate this far below the one at the simulated mass has dropped."""
CACHE_FILE = "ball_mass.json"
"""Where the measurement is kept, in the layout file's folder (a run's directory)."""


def with_ball_mass(scenario, factor: float):
    """``scenario`` with every moving ball's mass (or density) times ``factor``."""
    objects = {}
    for name, obj in scenario.objects.items():
        p = obj.physical
        if obj.part == "ball" and not p.static:
            p = dataclasses.replace(p, mass=None if p.mass is None else p.mass * factor,
                                    density=None if p.density is None else p.density * factor)
        objects[name] = dataclasses.replace(obj, physical=p)
    return dataclasses.replace(scenario, objects=objects)


def measure_ball_mass(scenario, values, parts, *, samples: int = 64, seed: int = 0,
                      factors=FACTORS, hand=None, physics=None) -> dict:
    """The success rate of the layout ``values`` (real, (d,)) under a hand (default: the
    default hand) and physical errors (default: the default ranges) with the balls' mass
    times each factor, on the same ``samples`` draws: ``{"factors", "rates": [{"factor",
    "rate", "interval", "successes", "samples", "lost", "gained"}], "kept": [low, high]
    (factors), "samples", "seed", "drop"}``. ``lost``/``gained``: draws that worked at the
    simulated mass and not at this one, and the other way round. A mass has dropped the
    figure where its rate is more than :data:`DROP` lower and the lost draws outnumber the
    gained ones beyond chance (one-sided sign test, 5 %). Simulated here, one process."""
    from scipy.stats import binomtest

    from rgmcad.runs.hand import DEFAULT_HAND
    from rgmcad.runs.problem import ScenarioContext
    from rgmcad.runs.robustness import wilson_interval
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsDraw
    from rgmcad.sim.run import Outcome

    hand = hand or DEFAULT_HAND
    ranges = hand.ranges(physics or DEFAULT_PHYSICS)
    x = vector_from_values(scenario, np.asarray(values, float))
    draws = [PhysicsDraw(ranges, seed, k) for k in range(samples)]
    factors = [float(f) for f in factors]
    worked = []
    for factor in factors:
        context = ScenarioContext(with_ball_mass(scenario, factor), parts)
        try:
            worked.append([context.simulate_one(x, known_valid=True, physics=d).outcome
                           is Outcome.SUCCESS for d in draws])
        finally:
            context.close()
    base = worked[factors.index(1.0)]
    rates, ok = [], []
    for factor, w in zip(factors, worked, strict=True):
        wins = sum(w)
        low, high = wilson_interval(wins, samples)
        lost = sum(b and not a for a, b in zip(w, base, strict=True))
        gained = sum(a and not b for a, b in zip(w, base, strict=True))
        rates.append({"factor": factor, "rate": wins / samples, "interval": [float(low),
                      float(high)], "successes": wins, "samples": samples, "lost": lost,
                      "gained": gained})
        beyond_chance = lost > gained and binomtest(lost, lost + gained, 0.5,
                                                    alternative="greater").pvalue < 0.05
        ok.append(not (sum(base) - wins > DROP * samples and beyond_chance))
    low = high = factors.index(1.0)
    while low > 0 and ok[low - 1]:
        low -= 1
    while high < len(factors) - 1 and ok[high + 1]:
        high += 1
    return {"factors": factors, "rates": rates, "kept": [factors[low], factors[high]],
            "samples": samples, "seed": seed, "drop": DROP, "hand": hand.to_json(),
            "physics": ranges.to_json()}


def cache_key(scenario_path, values) -> str:
    """The scenario file's digest and the layout's values, as the cache's key."""
    from rgmcad.runs.problem import scenario_digest

    return scenario_digest(scenario_path) + ":" + ",".join(f"{float(v):.9g}" for v in values)


def read_cached(folder, scenario_path, values) -> dict | None:
    """The measurement kept in ``folder`` for this scenario file and layout, else None."""
    path = Path(folder) / CACHE_FILE
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("key") != cache_key(scenario_path, values):
        return None
    return data


def write_cached(folder, scenario_path, values, measured: dict) -> Path:
    """Keep ``measured`` in ``folder`` for this scenario file and layout."""
    from rgmcad.files import write_atomic

    path = Path(folder) / CACHE_FILE
    write_atomic(path, json.dumps({"key": cache_key(scenario_path, values), **measured},
                                  indent=1))
    return path
