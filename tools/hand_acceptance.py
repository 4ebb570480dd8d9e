"""How often the optimised layout works when built by hand, against the user's own layout,
and whether it depends on how wide a range was typed (issue 52's acceptance).

For each scenario: ``rgmcad optimize`` (its summary's hand figure: every part within +-2 mm
and +-2 degrees, physical errors on, seed 0), and the scenario's reference layout (``solved``
for the shipped ones, ``hand`` for the held-out ones) measured the same way, on the same
draws. With ``--double PARAM``: the scenario again with that parameter's range twice as wide
(about its middle, clipped at 0 for a height), optimised with the same seed.

Results go to a JSON file as they come (a killed run resumes where it stopped):

    uv run python tools/hand_acceptance.py scenarios/simple.toml scenarios/ballrun.toml \\
        [--budget default] [--double track.x] [--out docs/hand-acceptance.json]
"""

import argparse
import json
import re
import sys
import time
from pathlib import Path

from rgmcad.reference.results import hand_table
from rgmcad.runs.executor import make_executor
from rgmcad.runs.hand import DEFAULT_HAND, HAND_SETTINGS, Builds, measure_rate
from rgmcad.runs.hand_text import hand_headline
from rgmcad.runs.problem import ScenarioProblem
from rgmcad.runs.workflow import optimize_scenario
from rgmcad.scene.design_space import vector_from_values
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.perturbation import DEFAULT_PHYSICS
from rgmcad.sim.revision import PHYSICS_REVISION


def reference_rate(path: str, layout: str, seed: int, workers: int) -> dict:
    """The hand figure of a named layout, as optimize measures its result."""
    problem = ScenarioProblem(path)
    scenario = problem.scenario
    x = vector_from_values(scenario, resolve_layout(scenario, layout, None)[1])
    executor = make_executor(workers, problem.context)
    s = HAND_SETTINGS["default"]
    start = time.perf_counter()
    try:
        rate = measure_rate(lambda d: Builds(executor)(x, d), DEFAULT_HAND, DEFAULT_PHYSICS,
                            seed, precision=s.precision, batch=s.batch, minimum=s.minimum,
                            maximum=s.maximum)
    finally:
        executor.close()
    return {**rate.to_json(), "seconds": time.perf_counter() - start}


def doubled(path: Path, parameter: str, folder: Path) -> Path:
    """A copy of the scenario with ``parameter``'s range twice as wide about its middle."""
    obj, component = parameter.split(".")
    text = path.read_text()
    block = re.search(rf"^\[objects\.{re.escape(obj)}\]\n(.*?)(?=^\[|\Z)", text, re.M | re.S)
    line = re.search(r"^free\s*=\s*\{.*\}$", block.group(1), re.M)
    entry = re.search(rf"\b{component}\s*=\s*\[\s*([-\d.eE+]+)\s*,\s*([-\d.eE+]+)\s*\]",
                      line.group(0))
    low, high = float(entry.group(1)), float(entry.group(2))
    half = high - low
    new_low, new_high = low - half / 2, high + half / 2
    if component == "z":
        new_low = max(new_low, 0.0)
    new_line = line.group(0).replace(entry.group(0),
                                     f"{component} = [{new_low:.6g}, {new_high:.6g}]")
    start = block.start(1) + line.start()
    out = folder / f"{path.stem}-wide-{obj}-{component}.toml"
    out.write_text(text[:start] + new_line + text[start + len(line.group(0)):])
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenarios", nargs="*")
    ap.add_argument("--budget", default="default")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--double", default=None, metavar="PARAM")
    ap.add_argument("--out", default="docs/hand-acceptance.json")
    ap.add_argument("--runs", default="runs/hand-acceptance")
    ap.add_argument("--table", action="store_true", help="print the results file as markdown")
    args = ap.parse_args()
    out = Path(args.out)
    results = json.loads(out.read_text()) if out.is_file() else {}
    if args.table:
        print(hand_table(results))
        return 0
    for given in args.scenarios:
        path = Path(given)
        if args.double:
            path = doubled(path, args.double, Path(args.runs).parent)
            Path(args.runs).mkdir(parents=True, exist_ok=True)
        key = f"{path.stem}:{args.budget}:s{args.seed}"
        if key in results:
            print(f"{key}: done before", file=sys.stderr)
            continue
        start = time.perf_counter()
        done = optimize_scenario(str(path), seed=args.seed, budget=args.budget,
                                 run_dir=Path(args.runs) / key.replace(":", "-"),
                                 workers=args.workers)
        summary = done.summary
        entry = {"scenario": str(path), "budget": args.budget, "seed": args.seed,
                 "optimum": summary["hand"]["hand"], "source": summary["source"],
                 "weak_links": summary["hand"]["weak_links"][:3],
                 "hand_choice": summary.get("hand_choice"),
                 "simulations": summary["simulations"],
                 "simulations_by_stage": summary["simulations_by_stage"],
                 "optimize_seconds": time.perf_counter() - start,
                 "headline": hand_headline(summary["hand"]),
                 "physics_revision": PHYSICS_REVISION}
        if not args.double:
            scenario = problem_layouts(str(path))
            reference = "solved" if "solved" in scenario else "hand" if "hand" in scenario \
                else None
            if reference:
                entry["reference"] = {"layout": reference, **reference_rate(
                    str(path), reference, args.seed, args.workers)}
        results[key] = entry
        out.write_text(json.dumps(results, indent=1))
        ref = entry.get("reference")
        print(f"{key}: optimum {entry['optimum']['rate']:.3f} {entry['optimum']['interval']}"
              + (f"; {ref['layout']} {ref['rate']:.3f} {ref['interval']}" if ref else "")
              + f" ({entry['optimize_seconds']:.0f} s)", flush=True)
    return 0


def problem_layouts(path: str) -> dict:
    from rgmcad.scene.loader import load_scenario

    return load_scenario(path).layouts


if __name__ == "__main__":
    sys.exit(main())
