"""How robust can a layout of this scenario be at all? A measured ceiling for rho_g.

Table 1 compares methods with each other; this asks how far the best of them is from the most
robust layout the simulator allows. It simulates one scrambled Sobol set of N valid layouts
(validity tests free), scores every successful one by the dense-set estimate of rho_g
(:mod:`rgmcad.runs.dense`, Sobol points only), and evaluates the K best, at least
``--spacing`` apart, with our protocol (``samples`` valid layouts per radius, the
benchmark's evaluation draws of trial ``--seeds``), so that the ceiling is stated in the
same units as Table 1. With a finished benchmark (``--benchmark``) it also scores the
methods' layouts by the dense estimate and reports each method's mean as a share of the
ceiling.

rho_g(x) averages success over balls of radius up to 1, so it varies slowly with x: in low
dimension (d <= 5) a set of a few thousand points leaves no large gap for a better layout
to hide in. In high dimension the dense estimate at small radii has no points and the
ceiling is only a lower bound (a layout at least this robust exists).

    nice -n 10 uv run python tools/robustness_ceiling.py --scenario scenarios/causality_switch.toml
        --out DIR [--n 4096] [--top 5] [--samples 20] [--seeds 0] [--benchmark DIR]
        [--workers 2]

Every simulation is journaled under ``--out`` (a killed run resumes); writes
``ceiling.json`` and ``ceiling.md`` there and prints the latter.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from rgmcad.files import write_atomic, write_json_atomic
from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.benchmark import evaluate_trial
from rgmcad.runs.dense import dense_curve, dense_valid_set, simulated_outcomes
from rgmcad.runs.executor import make_executor
from rgmcad.runs.problem import ScenarioProblem, scenario_digest
from rgmcad.runs.store import RecordedProblem, RunStore
from rgmcad.scene.perturbation import DEFAULT_PHYSICS


class _Quiet:
    """The progress object :func:`evaluate_trial` expects, printing every 100 simulations."""

    def __init__(self, what: str):
        self.what, self.n, self.t = what, 0, time.perf_counter()

    def simulated(self, *_record) -> None:
        self.n += 1
        if self.n % 100 == 0:
            print(f"  {self.what}: {self.n} ({time.perf_counter() - self.t:.0f} s)",
                  file=sys.stderr, flush=True)


def _dense_scores(points: np.ndarray, success: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Dense-set rho_g of each row of ``at`` (Sobol points only; no bootstrap)."""
    return np.array([dense_curve(x, points, success, boot=0).rho_g for x in at])


def _spread_top(candidates: np.ndarray, scores: np.ndarray, k: int, spacing: float):
    """Indices of the ``k`` best-scored candidates, each at least ``spacing`` from those
    already taken (so the evaluations do not spend themselves on one hill)."""
    taken: list[int] = []
    for i in np.argsort(-scores):
        if all(np.linalg.norm(candidates[i] - candidates[j]) >= spacing for j in taken):
            taken.append(int(i))
        if len(taken) == k:
            break
    return taken


def _benchmark_layouts(bench_dir: Path, name: str) -> tuple[dict, list[dict]]:
    table = json.loads((bench_dir / "benchmark.json").read_text())
    if table["scenario"] != name:
        sys.exit(f"{bench_dir}: a benchmark of {table['scenario']!r}, not of {name!r}")
    rows = [{"method": row["method"], "seed": seed, "vector": x, "rho_g": r}
            for row in table["rows"]
            for seed, x, r in zip(table["seeds"], row["vectors"], row["rho_g"], strict=True)]
    return table, rows


def _markdown(name: str, out: dict) -> str:
    lines = [f"# Robustness ceiling: {name}", "",
             f"{out['n_dense']} valid Sobol layouts simulated ({out['n_dense_success']} "
             f"succeed); every success scored by the dense-set rho_g (Sobol points only); the "
             f"{len(out['top'])} best, at least {out['spacing']} apart, evaluated with our "
             f"protocol ({out['samples']} valid layouts per radius, evaluation draws of trial "
             f"seed(s) {', '.join(map(str, out['seeds']))}).", "",
             "| rank | dense rho_g | rho_g, our protocol (mean over seeds) | "
             "per seed [95 % interval] | vector |",
             "|---|---|---|---|---|"]
    for i, t in enumerate(out["top"]):
        per = "; ".join(f"{e['rho_g']:.3f} [{e['interval'][0]:.3f}, {e['interval'][1]:.3f}]"
                        for e in t["evaluations"])
        lines.append(f"| {i + 1} | {t['dense_rho_g']:.3f} | {t['rho_g_mean']:.3f} | {per} | "
                     + ", ".join(f"{v:.3f}" for v in t["vector"]) + " |")
    with_physics = [t for t in out["top"] if all("physics" in e for e in t["evaluations"])]
    lines += [f"| {out['top'].index(t) + 1} (+ physical errors) | | "
              f"{np.mean([e['physics'] for e in t['evaluations']]):.3f} | "
              + "; ".join(f"{e['physics']:.3f}" for e in t["evaluations"]) + " | |"
              for t in with_physics]
    lines += ["", f"**Ceiling** (best evaluated): {out['ceiling']:.3f}.", ""]
    if "methods" in out:
        lines += ["| method | mean rho_g (benchmark) | share of the ceiling | mean dense rho_g "
                  "of its layouts | best dense rho_g of any Sobol success |", "|---|---|---|---|---|"]
        for m, v in out["methods"].items():
            lines.append(f"| {m} | {v['rho_g_mean']:.3f} | {v['share']:.2f} | "
                         f"{v['dense_mean']:.3f} | {out['dense_best']:.3f} |")
        lines.append("")
    lines.append(f"Simulations: {out['simulations']} (dense set {out['n_dense']}, evaluations "
                 f"{out['simulations'] - out['n_dense']}); wall {out['wall_time']:.0f} s.")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--n", type=int, default=4096, help="valid Sobol layouts to simulate")
    ap.add_argument("--top", type=int, default=5, help="layouts to evaluate with our protocol")
    ap.add_argument("--spacing", type=float, default=0.1,
                    help="least distance between two evaluated layouts (normalised units)")
    ap.add_argument("--samples", type=int, default=20, help="valid layouts per radius")
    ap.add_argument("--seeds", default="0",
                    help="evaluation draws: the benchmark trial seeds, e.g. 0,1,2")
    ap.add_argument("--seed", type=int, default=0, help="the Sobol set's scramble")
    ap.add_argument("--benchmark", default=None, help="a finished benchmark's folder")
    ap.add_argument("--physics", action="store_true",
                    help="also evaluate under placement plus physical errors (default ranges)")
    ap.add_argument("--workers", type=int, default=2, choices=(1, 2))
    ap.add_argument("--build", default=str(DEFAULT_BUILD_DIR))
    args = ap.parse_args()
    t0 = time.perf_counter()
    out_dir = Path(args.out)
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    problem = ScenarioProblem(args.scenario, args.build)
    base = {"format": 1, "scenario": problem.scenario.name,
            "scenario_sha256": scenario_digest(args.scenario), "seed": args.seed}
    events = list(problem.scenario.events)
    executor = make_executor(args.workers, problem.context)
    simulations = 0
    try:
        with RunStore(out_dir / f"dense-s{args.seed}", {**base, "kind": "dense-set"},
                      dimension=problem.dimension, events=events) as store:
            rec = RecordedProblem(problem, store, executor)
            X = dense_valid_set(rec.validity, problem.dimension, args.n, args.seed)
            ok, valid, _ = simulated_outcomes(rec, X, 512, lambda done: print(
                f"  dense set: {done}/{len(X)} ({time.perf_counter() - t0:.0f} s)",
                file=sys.stderr, flush=True))
            X, ok = X[valid], ok[valid]
            simulations += len(X)
        winners = X[ok]
        scores = _dense_scores(X, ok, winners)
        top = []
        for rank, i in enumerate(_spread_top(winners, scores, args.top, args.spacing)):
            evaluations = []
            for seed in seeds:
                identity = {**base, "kind": "ceiling-evaluation", "rank": rank,
                            "vector": winners[i].tolist(), "eval_seed": seed,
                            "samples": args.samples}
                e = evaluate_trial(identity, out_dir / f"eval-{rank}-s{seed}", problem, executor,
                                   winners[i], args.samples, seed, _Quiet(f"layout {rank + 1}"),
                                   physics=DEFAULT_PHYSICS if args.physics else None)
                simulations += e["simulations"]
                evaluations.append({"seed": seed, "rho_g": e["rho_g"],
                                    "interval": e["rho_g_interval"]})
                if e["physics"] is not None:
                    simulations += e["physics"]["simulations"]
                    evaluations[-1]["physics"] = e["physics"]["rho_g"]
            top.append({"vector": winners[i].tolist(), "dense_rho_g": float(scores[i]),
                        "rho_g_mean": float(np.mean([e["rho_g"] for e in evaluations])),
                        "evaluations": evaluations})
    finally:
        executor.close()
    out = {"scenario": base["scenario"], "n_dense": int(len(X)),
           "n_dense_success": int(ok.sum()), "spacing": args.spacing, "samples": args.samples,
           "seeds": seeds, "top": top, "dense_best": float(scores.max()) if len(scores) else 0.0,
           "ceiling": max((t["rho_g_mean"] for t in top), default=0.0),
           "simulations": simulations, "wall_time": time.perf_counter() - t0}
    if args.benchmark:
        table, rows = _benchmark_layouts(Path(args.benchmark), base["scenario"])
        dense = _dense_scores(X, ok, np.array([r["vector"] for r in rows]))
        out["methods"] = {}
        for row in table["rows"]:
            m = row["method"]
            mine = [d for d, r in zip(dense, rows, strict=True) if r["method"] == m]
            out["methods"][m] = {"rho_g_mean": row["rho_g_mean"],
                                 "share": row["rho_g_mean"] / out["ceiling"] if out["ceiling"]
                                 else float("nan"), "dense_mean": float(np.mean(mine))}
    write_json_atomic(out_dir / "ceiling.json", out)
    md = _markdown(base["scenario"], out)
    write_atomic(out_dir / "ceiling.md", md)
    print(md)


if __name__ == "__main__":
    main()
