"""Does the authors' dense-set robustness protocol rank layouts as ours does, and at what cost?

Simulates one scrambled Sobol set of N valid layouts of the scenario once (validity tests
free, invalid points dropped), then, for every layout a finished benchmark returned
(``benchmark.json``'s per-method ``vectors``), 100 local points uniform in the cube
``x +- eta`` plus ``x`` itself, and estimates rho_l and rho_g the authors' way
(:mod:`rgmcad.runs.dense`). Compares with the benchmark's own rho_g per layout (our
protocol: ``samples`` valid layouts per radius): Kendall tau and Spearman over all layouts,
each method's mean and their order, per-layout differences against the two estimates'
sampling errors, the mean curves' difference per radius, the part of rho_g from the radii
>= ``--cut`` on the Sobol points alone, how many Sobol points fall in the small balls, and
the cost in simulations. Every simulation is journaled in a RunStore under
``--out`` (``dense-s{seed}/``, ``local-s{seed}/``): a killed run resumes. ``--sizes`` also
analyses prefixes of the same set (the first n valid points: what ``--n n`` would give).

    nice -n 10 uv run python tools/dense_protocol.py --benchmark DIR --out DIR
        [--scenario scenarios/ballrun.toml] [--n 16384] [--sizes 4096] [--seed 0]
        [--workers 2] [--local 100]

Writes ``dense_protocol.json`` and ``dense_protocol.md`` under ``--out`` and prints the latter.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import kendalltau, spearmanr

from rgmcad.files import write_atomic, write_json_atomic
from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.dense import (
    balls_of,
    dense_curve,
    dense_valid_set,
    local_points,
    simulated_outcomes,
)
from rgmcad.runs.executor import make_executor
from rgmcad.runs.problem import ScenarioProblem, scenario_digest
from rgmcad.runs.robustness import EPS_GRID
from rgmcad.runs.store import RecordedProblem, RunStore

Z = 1.959964


def _layouts(bench_dir: Path) -> tuple[dict, list[dict]]:
    """The benchmark table and one entry per evaluated layout (method, seed, vector, rho_g,
    and where its evaluation is still on disk: its interval, curve and simulation seconds)."""
    table = json.loads((bench_dir / "benchmark.json").read_text())
    out = []
    for row in table["rows"]:
        m = row["method"]
        tag = m if m in ("ours", "full") else f"{m}-B{table['budget_sims']}"
        for seed, x, rho_g in zip(table["seeds"], row["vectors"], row["rho_g"], strict=True):
            entry = {"method": m, "seed": seed, "vector": x, "rho_g": rho_g}
            ev = bench_dir / "eval" / tag / f"t{seed}"
            if (ev / "trial.json").is_file():
                done = json.loads((ev / "trial.json").read_text())
                entry.update(interval=done["rho_g_interval"], rho=done["rho"],
                             simulations=done["simulations"])
                lines = (ev / "simulations.jsonl").read_text().splitlines()
                entry["seconds"] = sum(json.loads(s)["seconds"] for s in lines if s.strip())
            out.append(entry)
    return table, out


def _simulate(recorded: RecordedProblem, X: np.ndarray, what: str):
    """Outcomes (success bool, valid bool) and simulation seconds of the rows of X, journaled."""
    t = time.perf_counter()
    return simulated_outcomes(recorded, X, on_chunk=lambda done: print(
        f"  {what}: {done}/{len(X)} ({time.perf_counter() - t:.0f} s)", file=sys.stderr,
        flush=True))


def _large_radii(layouts, dense_X, dense_ok, curves_ours, cut: float) -> dict:
    """The share of rho_g from the radii >= ``cut``: Sobol points alone (no local points)
    against ours' curve on the same radii; where the dense set is dense enough."""
    big = EPS_GRID >= cut - 1e-9
    w = np.trapezoid(np.eye(len(EPS_GRID)), EPS_GRID, axis=1)[big]
    dense, fewest = [], []
    for e in layouts:
        k = balls_of(e["vector"], dense_X)
        c = np.cumsum(np.bincount(k, None, len(EPS_GRID) + 1))[:-1]
        s = np.cumsum(np.bincount(k, dense_ok, len(EPS_GRID) + 1))[:-1]
        dense.append(w @ np.where(c > 0, s / np.maximum(c, 1), 0.0)[big])
        fewest.append(int(c[big].min()))
    ours = curves_ours[:, big] @ w
    diff = np.array(dense) - ours
    return {"cut": cut, "radii": int(big.sum()), "fewest_sobol_points": min(fewest),
            "kendall_tau": kendalltau(dense, ours)[0], "spearman": spearmanr(dense, ours)[0],
            "difference_mean": float(diff.mean()), "difference_sd": float(diff.std(ddof=1))}


def _analyse(layouts, dense_X, dense_ok, locals_, samples: int, n_local_sims: int,
             cut: float) -> dict:
    curves = [dense_curve(e["vector"], dense_X, dense_ok, L, Ls, rng=i)
              for i, (e, (L, Ls)) in enumerate(zip(layouts, locals_, strict=True))]
    dense = np.array([c.rho_g for c in curves])
    dense_se = np.array([(c.rho_g_high - c.rho_g_low) / (2 * Z) for c in curves])
    ours = np.array([e["rho_g"] for e in layouts])
    diff = dense - ours
    tau, rho = kendalltau(dense, ours), spearmanr(dense, ours)
    out = {"n": len(dense_X), "kendall_tau": tau[0], "kendall_p": tau[1],
           "spearman": rho[0], "spearman_p": rho[1],
           "difference_mean": float(diff.mean()), "difference_sd": float(diff.std(ddof=1)),
           "difference_max_abs": float(np.abs(diff).max()),
           "dense_se_mean": float(dense_se.mean())}
    if all("interval" in e for e in layouts):
        ours_se = np.array([(e["interval"][1] - e["interval"][0]) / (2 * Z) for e in layouts])
        zs = diff / np.sqrt(dense_se**2 + ours_se**2)
        out.update(ours_se_mean=float(ours_se.mean()), z_abs_mean=float(np.abs(zs).mean()),
                   beyond_2se=int((np.abs(zs) > 2).sum()))
        rho_ours = np.array([e["rho"] for e in layouts])
        out["curve_difference"] = (np.array([c.rho for c in curves]) - rho_ours).mean(0).tolist()
        out["large_radii"] = _large_radii(layouts, dense_X, dense_ok, rho_ours, cut)
    methods = list(dict.fromkeys(e["method"] for e in layouts))
    means = {m: {"dense": float(np.mean([d for d, e in zip(dense, layouts, strict=True)
                                         if e["method"] == m])),
                 "ours": float(np.mean([o for o, e in zip(ours, layouts, strict=True)
                                        if e["method"] == m]))} for m in methods}
    out["method_means"] = means
    out["order_dense"] = sorted(methods, key=lambda m: -means[m]["dense"])
    out["order_ours"] = sorted(methods, key=lambda m: -means[m]["ours"])
    out["method_kendall_tau"] = kendalltau([means[m]["dense"] for m in methods],
                                           [means[m]["ours"] for m in methods])[0]
    # Sobol points (local points excluded) per ball, averaged over the layouts
    sobol_in = np.array([np.cumsum(np.bincount(balls_of(e["vector"], dense_X), None,
                                               len(EPS_GRID) + 1))[:-1] for e in layouts])
    out["sobol_points_per_ball"] = sobol_in.mean(0).tolist()
    out["layouts"] = [{"method": e["method"], "seed": e["seed"], "rho_g_ours": e["rho_g"],
                       "rho_g_dense": float(d), "dense_se": float(s),
                       "local_rho": float(np.mean(Ls)) if len(Ls) else None}
                      for e, d, s, (_, Ls) in zip(layouts, dense, dense_se, locals_, strict=True)]
    out["simulations_dense"] = len(dense_X) + n_local_sims
    out["simulations_ours"] = int(sum(e.get("simulations", 30 * samples) for e in layouts))
    return out


def _markdown(name: str, results: list[dict], costs: dict) -> str:
    lines = [f"# Dense-set protocol against ours: {name}", ""]
    for r in results:
        lines += [f"## N = {r['n']}", "",
                  f"- Kendall tau {r['kendall_tau']:.3f} (p {r['kendall_p']:.2g}), Spearman "
                  f"{r['spearman']:.3f} (p {r['spearman_p']:.2g}) over "
                  f"{len(r['layouts'])} layouts",
                  f"- dense - ours per layout: mean {r['difference_mean']:+.3f}, sd "
                  f"{r['difference_sd']:.3f}, max |.| {r['difference_max_abs']:.3f}; s.e. "
                  f"dense {r['dense_se_mean']:.3f}"
                  + (f", ours {r['ours_se_mean']:.3f}; {r['beyond_2se']} layouts beyond 2 "
                     f"combined s.e. (mean |z| {r['z_abs_mean']:.2f})" if "ours_se_mean" in r
                     else ""),
                  "- method order, dense: " + " > ".join(r["order_dense"]),
                  "- method order, ours:  " + " > ".join(r["order_ours"]) +
                  f" (Kendall tau of the means {r['method_kendall_tau']:.2f})",
                  f"- simulations: dense {r['simulations_dense']} (N once + local), ours "
                  f"{r['simulations_ours']}",
                  "- Sobol points per ball (mean over layouts), eps: " + ", ".join(
                      f"{e:.3f}: {c:.2f}" for e, c in zip(EPS_GRID, r["sobol_points_per_ball"],
                                                          strict=True) if e <= 0.55), "",
                  "| method | seed | rho_g ours | rho_g dense (s.e.) | local success |",
                  "|---|---|---|---|---|"]
        lines += [f"| {e['method']} | {e['seed']} | {e['rho_g_ours']:.3f} | "
                  f"{e['rho_g_dense']:.3f} ({e['dense_se']:.3f}) | {e['local_rho']:.2f} |"
                  for e in r["layouts"]]
        lines += ["", "| method | mean rho_g ours | mean rho_g dense |", "|---|---|---|"]
        lines += [f"| {m} | {v['ours']:.3f} | {v['dense']:.3f} |"
                  for m, v in r["method_means"].items()]
        if "curve_difference" in r:
            lines += ["", "Mean rho_l difference (dense - ours) per eps: " + ", ".join(
                f"{e:.2f}: {d:+.2f}" for e, d in zip(EPS_GRID, r["curve_difference"],
                                                     strict=True))]
            b = r["large_radii"]
            lines += ["", f"Radii eps >= {b['cut']} only ({b['radii']} radii, at least "
                      f"{b['fewest_sobol_points']} Sobol points each; Sobol points alone): "
                      f"dense - ours {b['difference_mean']:+.3f} (sd {b['difference_sd']:.3f}), "
                      f"Kendall tau {b['kendall_tau']:.3f}, Spearman {b['spearman']:.3f}"]
        lines.append("")
    lines += [f"Simulation seconds (one core): dense set {costs['dense_seconds']:.0f}, local "
              f"points {costs['local_seconds']:.0f}, ours {costs['ours_seconds']:.0f}", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenario", default="scenarios/ballrun.toml")
    ap.add_argument("--benchmark", required=True, help="a finished benchmark's folder")
    ap.add_argument("--out", required=True)
    ap.add_argument("--n", type=int, default=1 << 14, help="valid Sobol points")
    ap.add_argument("--sizes", default="", help="smaller prefixes to analyse too, e.g. 4096")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=2, choices=(1, 2))
    ap.add_argument("--local", type=int, default=100, help="local points per layout")
    ap.add_argument("--cut", type=float, default=0.4,
                    help="radii >= this also compared on the Sobol points alone")
    ap.add_argument("--build", default=str(DEFAULT_BUILD_DIR))
    args = ap.parse_args()
    out = Path(args.out)
    table, layouts = _layouts(Path(args.benchmark))
    problem = ScenarioProblem(args.scenario, args.build)
    base = {"format": 1, "scenario": problem.scenario.name,
            "scenario_sha256": scenario_digest(args.scenario), "seed": args.seed}
    events = list(problem.scenario.events)
    executor = make_executor(args.workers, problem.context)
    try:
        with RunStore(out / f"dense-s{args.seed}", {**base, "kind": "dense-set"},
                      dimension=problem.dimension, events=events) as store:
            rec = RecordedProblem(problem, store, executor)
            X = dense_valid_set(rec.validity, problem.dimension, args.n, args.seed)
            ok, valid, dense_seconds = _simulate(rec, X, "dense set")
            X, ok = X[valid], ok[valid]
        with RunStore(out / f"local-s{args.seed}", {**base, "kind": "dense-local",
                                                    "local": args.local},
                      dimension=problem.dimension, events=events) as store:
            rec = RecordedProblem(problem, store, executor)
            cands = [np.vstack([e["vector"], local_points(
                e["vector"], args.local, np.random.default_rng([args.seed, i]))])
                for i, e in enumerate(layouts)]
            cands = [C[rec.validity(C)] for C in cands]
            s, _, local_seconds = _simulate(rec, np.vstack(cands), "local points")
            bounds = np.cumsum([0, *map(len, cands)])
            locals_ = [(C, s[bounds[i]:bounds[i + 1]]) for i, C in enumerate(cands)]
    finally:
        executor.close()
    sizes = sorted({args.n, *(int(v) for v in args.sizes.split(",") if v)})
    results = [_analyse(layouts, X[:n], ok[:n], locals_, table["samples_per_radius"],
                        int(bounds[-1]), args.cut) for n in sizes]
    costs = {"dense_seconds": dense_seconds, "local_seconds": local_seconds,
             "ours_seconds": sum(e.get("seconds", 0.0) for e in layouts)}
    write_json_atomic(out / "dense_protocol.json", {"scenario": base["scenario"],
                                                    "results": results, **costs})
    md = _markdown(base["scenario"], results, costs)
    write_atomic(out / "dense_protocol.md", md)
    print(md)


if __name__ == "__main__":
    main()
