"""How far off a ball's mass may be before the built-by-hand figure drops, by simulation.

The balls of a layout (objects of the ``ball`` family that move) are given their simulated
mass times each of :data:`FACTORS`, and the layout is built ``samples`` times at each mass
under the same hand's and physical errors (:func:`rgmcad.runs.hand.measure_rate`, the same
draws at every mass: common random numbers, so the rates differ by the mass alone). A mass
keeps the figure while its rate is at most :data:`DROP` below the rate at the simulated
mass; the range kept is the run of such factors around 1.

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
    times each factor: ``{"factors", "rates": [HandRate JSON], "kept": [low, high] (factors),
    "samples", "seed"}``. Simulated here, one process."""
    from rgmcad.runs.hand import DEFAULT_HAND, measure_rate
    from rgmcad.runs.problem import ScenarioContext
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.perturbation import DEFAULT_PHYSICS

    hand = hand or DEFAULT_HAND
    physics = physics or DEFAULT_PHYSICS
    x = vector_from_values(scenario, np.asarray(values, float))
    rates = []
    for factor in factors:
        context = ScenarioContext(with_ball_mass(scenario, factor), parts)
        try:
            def simulate(draws, context=context):
                return [context.simulate_one(x, known_valid=True, physics=d) for d in draws]

            rates.append(measure_rate(simulate, hand, physics, seed, batch=samples,
                                      minimum=samples, maximum=samples).to_json())
        finally:
            context.close()
    factors = [float(f) for f in factors]
    base = rates[factors.index(1.0)]["rate"]
    ok = [r["rate"] >= base - DROP for r in rates]
    k = factors.index(1.0)
    low = high = k
    while low > 0 and ok[low - 1]:
        low -= 1
    while high < len(factors) - 1 and ok[high + 1]:
        high += 1
    return {"factors": factors, "rates": rates, "kept": [factors[low], factors[high]],
            "samples": samples, "seed": seed, "drop": DROP}


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
