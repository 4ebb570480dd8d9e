"""How much a layout's outcome depends on the time step and the solver's iterations.

For each scenario, its ``solved`` layout is simulated with its ``[simulation]`` settings as
written and with three variants (half the time step, twice the solver iterations, both): once
as designed (the nominal outcome) and built by hand ``--draws`` times (every part within +-2 mm
and +-2 degrees, physical errors on, seed 0: the draws of ``rgmcad evaluate``'s headline).
Draw ``k`` is the same build under every variant (common random numbers), so each variant's
builds are compared pair by pair with the settings as written: how many flipped each way.
Variants alternate draw by draw, so a change in the machine's load falls on all of them alike.
The paired p is the exact McNemar test of the flips (two-sided): small when a variant's builds
flip one way more often than chance would.

Prints a markdown table (docs/explanation/physics-settings.md). Results go to a JSON file as
they come (a killed run resumes where it stopped; a finished one only prints its table):

    uv run python tools/physics_settings.py [scenarios/simple.toml ...] [--draws 64] \\
        [--out docs/physics-settings.json]
"""

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from rgmcad.files import write_json_atomic
from rgmcad.reference.results import physics_settings_table
from rgmcad.runs.hand import DEFAULT_HAND
from rgmcad.runs.problem import ScenarioContext
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsDraw
from rgmcad.sim.revision import PHYSICS_REVISION

SCENARIOS = ["simple", "ballrun", "branching", "causality_switch", "long_chain", "teapot"]
VARIANTS = {"as written": (1.0, 1), "dt / 2": (0.5, 1), "iterations x 2": (1.0, 2),
            "dt / 2, iterations x 2": (0.5, 2)}
"""Name -> (time step factor, solver iterations factor)."""


def contexts(path: str) -> dict[str, ScenarioContext]:
    """One context per variant (each its own engine), the parts loaded once."""
    base = ScenarioContext.load(path)
    out = {}
    for name, (dt, iterations) in VARIANTS.items():
        s = base.scenario.settings
        settings = dataclasses.replace(s, timestep=s.timestep * dt,
                                       solver_iterations=s.solver_iterations * iterations)
        out[name] = ScenarioContext(dataclasses.replace(base.scenario, settings=settings),
                                    base.parts)
    return out


def measure(path: str, draws: int, seed: int, done: dict, save) -> dict:
    """Simulate what ``done`` (this scenario's stored results) lacks; ``save()`` after each
    draw. ``done``: {variant: {"settings", "nominal", "builds": [[outcome, s], ...]}}."""
    ctx = contexts(path)
    scenario = next(iter(ctx.values())).scenario
    values = values_from_mapping(scenario, scenario.layouts["solved"])
    for name, c in ctx.items():
        entry = done.setdefault(name, {"builds": []})
        entry["settings"] = {"timestep": c.scenario.settings.timestep,
                             "solver_iterations": c.scenario.settings.solver_iterations}
        if "nominal" not in entry:
            r = c.simulate_values(values)
            times = [t for _, t in r.events.values() if t is not None]
            entry["nominal"] = [r.outcome.value, max(times, default=None), r.seconds]
            save()
    ranges = DEFAULT_HAND.ranges(DEFAULT_PHYSICS)
    for k in range(min(len(e["builds"]) for e in done.values()), draws):
        for name, c in ctx.items():
            if len(done[name]["builds"]) > k:
                continue
            r = c.simulate_values(values, physics=PhysicsDraw(ranges, seed, k))
            done[name]["builds"].append([r.outcome.value, r.seconds])
        save()
        print(f"\r{Path(path).stem}: {k + 1}/{draws} builds", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    for c in ctx.values():
        c.close()
    return done


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenarios", nargs="*",
                        default=[f"scenarios/{s}.toml" for s in SCENARIOS])
    parser.add_argument("--draws", type=int, default=64, help="builds by hand per variant")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("docs/physics-settings.json"))
    args = parser.parse_args()
    results = json.loads(args.out.read_text()) if args.out.exists() else {}
    results.setdefault("seed", args.seed)
    results.setdefault("hand", DEFAULT_HAND.to_json())
    results.setdefault("physics", DEFAULT_PHYSICS.to_json())
    results.setdefault("scenarios", {})
    results.setdefault("physics_revision", PHYSICS_REVISION)
    if results["physics_revision"] != PHYSICS_REVISION:
        sys.exit(f"{args.out} was measured under the physics of {results['physics_revision']}, "
                 f"this code's is {PHYSICS_REVISION}; give another --out")
    if results["seed"] != args.seed:
        sys.exit(f"{args.out} holds seed {results['seed']}; give another --out")

    def save():
        write_json_atomic(args.out, results)

    for path in args.scenarios:
        done = results["scenarios"].setdefault(Path(path).stem, {})
        measure(path, args.draws, args.seed, done, save)
    print(physics_settings_table(results))


if __name__ == "__main__":
    main()
