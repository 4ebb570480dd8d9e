"""``rgmcad benchmark``: our method against the paper's baselines and CMA-ES, like the paper's
Table 1 and Fig. 15 (section 8.3; SPEC 5.6).

For each method, ``trials`` runs with seeds ``seed + i``; every method gets the same
simulation budget ``B`` (``budget_sims``, or the mean number of simulations our method used:
every one it ran, its final choice by simulation included; validity tests are free for every
method). Each returned layout is evaluated by one protocol,
:func:`~rgmcad.runs.robustness.local_robustness` with ``samples`` valid layouts per radius,
and with **common random numbers**: at trial ``i`` every method's layout is perturbed with
the same generator (seeded by ``seed + i``), so the draws differ only where the ball around
one layout leaves the cube or holds invalid layouts and another's does not. With physical
errors (``physics``, on by default), every evaluated layout is simulated a second time with a
physical draw (friction, masses, restitution): a second rho_g per trial, its own paired test,
and common random numbers for those draws too (draw ``k * n + j`` for the ``j``-th layout of
radius ``k``, under the trial's evaluation seed, whatever the method).

Everything is resumable: each method's trial and each evaluation is a run directory
(:class:`~rgmcad.runs.store.RunStore`: every simulation journaled, replayed on the next
call) under ``out/``, finished by a small ``trial.json``; the methods are deterministic given
their seed, so a benchmark killed at any point and run again gives the same table. Layout::

    out/ours/t{i}/              an ``rgmcad optimize`` run directory (out/full/t{i}: the
                                same with one global model, ``factorized=False``: Fig. 16)
    out/{method}-B{B}/t{i}/     a baseline's simulations and trial.json
    out/eval/{method}[-B{B}]/t{i}/   the evaluation of that trial's layout (the physical
                                draws are not journaled: an evaluation killed there redoes them)
    out/benchmark.md, benchmark.json, robustness.png

Times: ``time_s`` is the simulations' own seconds (from the journal, so a resumed trial
counts what its killed predecessor simulated) plus the method's computation outside the
simulations in the call that finished it: a cost on one core, independent of ``workers``.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from rgmcad.files import write_atomic, write_json_atomic
from rgmcad.parts.family import family_digest
from rgmcad.runs.checks import MAX_SAMPLES, MAX_SEED, check_range, check_workers
from rgmcad.runs.executor import make_executor, scheduler_from_env
from rgmcad.runs.problem import ScenarioProblem, scenario_digest, simulate_layout_task
from rgmcad.runs.store import RecordedProblem, RunStore
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsRanges

__all__ = ["METHODS", "DEFAULT_METHODS", "LEARNERS", "LABELS", "TRIAL", "TABLE_MD",
           "TABLE_JSON", "PLOT", "run_benchmark", "budget_of_ours", "evaluate_trial"]

METHODS = ("ours", "full", "b1", "b2", "b3", "cma")
DEFAULT_METHODS = ("ours", "b1", "b2", "b3", "cma")
LEARNERS = ("ours", "full")  # our method: factorised, and with one global model (Fig. 16)
LABELS = {"ours": "ours (factorised SPD)", "full": "ours, full SPD (one model)",
          "b1": "B1 random search",
          "b2": "B2 uniform + local robustness", "b3": "B3 GP optimisation (EI)",
          "cma": "CMA-ES"}
TRIAL = "trial.json"
TABLE_MD, TABLE_JSON, PLOT = "benchmark.md", "benchmark.json", "robustness.png"
_EVAL_STREAM = 0x5EEDE7A1  # the evaluation's generator: [seed + i, this]


def _read(path: Path) -> dict | None:
    try:
        data = json.loads(path.read_text())
        return data if isinstance(data, dict) else None
    except (OSError, ValueError):
        return None



class _Timed(RecordedProblem):
    """A recorded problem that adds up the time spent waiting for simulations and the
    simulations' own seconds (replayed ones included)."""

    wait_seconds = 0.0
    sim_seconds = 0.0

    def submit_records(self, X):
        wait = super().submit_records(X)

        def timed():
            t = time.perf_counter()
            records = wait()
            self.wait_seconds += time.perf_counter() - t
            self.sim_seconds += sum(r.seconds for r in records)
            return records

        return timed


def budget_of_ours(summary: dict) -> int:
    """Simulations of an ``optimize`` run counted in the budget: every simulation the method
    ran (exploration, active learning with its discarded labels, the final choice by
    simulation); validity tests are free, as for the baselines."""
    return int(summary.get("evaluations", summary["simulations"]))


def _ours(method: str, scenario_path, out: Path, seed: int, budget: str, settings, workers,
          build_dir, progress, scheduler=None, parts_dir=None) -> dict:
    """A trial of our method (``full``: one global model, ``factorized=False``)."""
    from dataclasses import replace

    from rgmcad.learning.settings import budget as budget_settings
    from rgmcad.runs.workflow import optimize_scenario

    run_dir = out / method / f"t{seed}"
    settings = budget_settings(budget) if settings is None else settings
    if method == "full":
        settings = replace(settings, factorized=False)
    done = _read(run_dir / TRIAL)
    if done is not None:
        return done
    timed: list[_Timed] = []

    def recorded(*args):
        timed.append(_Timed(*args))
        return timed[-1]

    start = time.perf_counter()
    run = optimize_scenario(scenario_path, seed=seed, budget=budget, settings=settings,
                            run_dir=run_dir, workers=workers, build_dir=build_dir,
                            progress=progress, recorded=recorded, scheduler=scheduler,
                            parts_dir=parts_dir)
    s = run.summary
    wall = time.perf_counter() - start
    overhead = wall - timed[0].wait_seconds if timed else 0.0
    trial = {"method": method, "seed": seed, "vector": s["vector"],
             "budget_sims": budget_of_ours(s), "simulations": s["simulations"],
             "score": s["probability"], "time_s": s["simulation_seconds"] + overhead}
    write_json_atomic(run_dir / TRIAL, trial)
    return trial


def _baseline(method: str, identity: dict, run_dir: Path, problem, executor, budget: int,
              seed: int, progress) -> dict:
    from rgmcad.learning.baselines import BASELINES

    done = _read(run_dir / TRIAL)
    if done is not None:
        return done
    scenario = problem.scenario
    with RunStore(run_dir, identity, dimension=problem.dimension,
                  events=list(scenario.events)) as store:
        recorded = _Timed(problem, store, executor, progress.simulated)
        start = time.perf_counter()
        r = BASELINES[method](recorded, budget, seed)
        overhead = time.perf_counter() - start - recorded.wait_seconds
        trial = {"method": method, "seed": seed, "vector": [float(v) for v in r.x],
                 "budget_sims": budget, "simulations": r.n_simulations,
                 "evaluations": r.n_evaluations, "score": r.score,
                 "time_s": recorded.sim_seconds + overhead}
        write_json_atomic(run_dir / TRIAL, trial)
    return trial


def evaluate_trial(identity: dict, run_dir: Path, problem, executor, x, samples: int,
                   seed: int, progress, physics: PhysicsRanges | None = None) -> dict:
    """Layout ``x`` evaluated as the benchmark's trial ``seed`` evaluates every method's layout
    (the same perturbation draws), journaled in ``run_dir``; a finished one is read back.
    ``progress.simulated(record, ...)`` is called per simulation."""
    from rgmcad.runs.robustness import local_robustness

    done = _read(run_dir / TRIAL)
    wanted = None if physics is None else physics.to_json()
    if done is not None and (wanted is None or (done.get("physics") or {}).get("ranges")
                             == wanted):
        return done
    with RunStore(run_dir, identity, dimension=problem.dimension,
                  events=list(problem.scenario.events)) as store:
        recorded = RecordedProblem(problem, store, executor, progress.simulated)

        def simulate(X, draws=None):  # the store is keyed by layout: physics goes around it
            if draws is None:
                return recorded.simulate_records(X)
            items = [(v, True, d) for v, d in zip(X, draws, strict=True)]
            return list(executor.map_context(simulate_layout_task, items))

        curve = local_robustness(np.asarray(x, dtype=float), recorded.validity, simulate,
                                 samples, np.random.default_rng([seed, _EVAL_STREAM]),
                                 physics=physics)
        out = {"vector": [float(v) for v in x], "seed": seed, "samples": samples,
               "rho_g": curve.rho_g, "rho_g_interval": [curve.rho_g_low, curve.rho_g_high],
               "eps": curve.eps.tolist(), "rho": curve.rho.tolist(),
               "counts": curve.counts.tolist(), "simulations": curve.simulations,
               "physics": None}
        if curve.physics is not None:
            p = curve.physics
            out["physics"] = {"ranges": wanted, "rho_g": p.rho_g,
                              "rho_g_interval": [p.rho_g_low, p.rho_g_high],
                              "rho": p.rho.tolist(), "simulations": p.simulations}
        write_json_atomic(run_dir / TRIAL, out)
    return out


def run_benchmark(scenario_path, out_dir, *, methods=DEFAULT_METHODS, trials: int = 10,
                  seed: int = 0, budget_sims: int | None = None, samples: int = 50,
                  ours_budget: str = "default", ours_settings=None,
                  workers: int | None = None, build_dir=None, progress=None,
                  scheduler: str | None = None, parts_dir=None,
                  physics: PhysicsRanges | None = DEFAULT_PHYSICS) -> dict:
    """Run (or continue) a benchmark and write its table and figure; returns the table
    (what ``benchmark.json`` holds). See the module docstring. ``scheduler``: a Dask
    scheduler's address or ``local:N`` (None: ``RGMCAD_SCHEDULER`` if set, else ``workers``
    processes); ``parts_dir``: the user's part families (``--parts``); ``physics``: the
    physical errors of the second rho_g (None: placement errors only)."""
    from rgmcad.errors import UsageError
    from rgmcad.parts.store import DEFAULT_BUILD_DIR
    from rgmcad.runs.workflow import RunProgress
    from rgmcad.scene.loader import load_scenario

    progress = progress or RunProgress()
    build_dir = DEFAULT_BUILD_DIR if build_dir is None else build_dir
    methods = tuple(methods)
    bad = [m for m in methods if m not in METHODS]
    if bad or not methods or len(set(methods)) != len(methods):
        raise UsageError("--methods", ",".join(methods), f"expected distinct names among "
                         f"{', '.join(METHODS)}")
    check_range(trials, 1, 1000, "--trials", "a number of trials")
    check_range(seed, 0, MAX_SEED - 1000, "--seed", "a base seed")
    check_range(samples, 1, MAX_SAMPLES, "--samples", "a number of layouts per radius")
    check_workers(workers)
    if budget_sims is not None:
        check_range(budget_sims, 1, 10**7, "--budget-sims", "a number of simulations")
    elif "ours" not in methods:
        raise UsageError("--budget-sims", "", "needed when ours is not among --methods (the "
                         "budget is otherwise the mean number of simulations ours used)")
    scenario = load_scenario(scenario_path, parts_dir=parts_dir)
    digest = scenario_digest(scenario_path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    seeds = [seed + i for i in range(trials)]
    found: dict[str, list[dict]] = {}
    for m in (m for m in methods if m in LEARNERS):
        for s in seeds:
            progress.stage(f"{m} t{s}")
            found.setdefault(m, []).append(_ours(
                m, scenario_path, out, s, ours_budget, ours_settings, workers, build_dir,
                progress, scheduler, parts_dir))
    budget = budget_sims if budget_sims is not None else int(
        np.floor(np.mean([t["budget_sims"] for t in found["ours"]])))
    problem = ScenarioProblem(scenario_path, build_dir, parts_dir)
    executor = make_executor(workers, problem.context, scheduler=scheduler_from_env(scheduler),
                             payload=problem.payload)
    base = {"format": 1, "scenario": scenario.name, "scenario_sha256": digest}
    if parts_dir is not None:  # other families, other results: not the same trials
        base["parts"] = {n: family_digest(f) for n, f in sorted(scenario.families.items())}
    tags = {m: m if m in LEARNERS else f"{m}-B{budget}" for m in methods}
    evaluations: dict[str, list[dict]] = {}
    try:
        for m in methods:
            if m in LEARNERS:
                continue
            for s in seeds:
                progress.stage(f"{m} t{s}")
                found.setdefault(m, []).append(_baseline(
                    m, {**base, "kind": "baseline", "method": m, "seed": s, "budget": budget},
                    out / tags[m] / f"t{s}", problem, executor, budget, s, progress))
        for m in methods:
            for s, trial in zip(seeds, found[m], strict=True):
                progress.stage(f"evaluate {m} t{s}")
                identity = {**base, "kind": "evaluation", "vector": trial["vector"],
                            "seed": s, "samples": samples}
                evaluations.setdefault(m, []).append(evaluate_trial(
                    identity, out / "eval" / tags[m] / f"t{s}", problem, executor,
                    trial["vector"], samples, s, progress, physics))
    finally:
        executor.close()
    table = _table(scenario.name, methods, seeds, budget, samples, found, evaluations)
    table["physics"] = None if physics is None else physics.to_json()
    table["wall_time"] = time.perf_counter() - start
    write_json_atomic(out / TABLE_JSON, table)
    write_atomic(out / TABLE_MD, table_markdown(table))
    plot_benchmark(table, out / PLOT)
    return table


def _mean_se(v) -> tuple[float, float | None]:
    v = np.asarray(v, dtype=float)
    se = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else None
    return float(v.mean()), se


def _table(name, methods, seeds, budget, samples, found, evaluations) -> dict:
    rows = []
    for m in methods:
        rho_g = [e["rho_g"] for e in evaluations[m]]
        curves = np.array([e["rho"] for e in evaluations[m]])
        mean, se = _mean_se(rho_g)
        row = {"method": m, "label": LABELS[m], "trials": len(rho_g), "rho_g_mean": mean,
               "rho_g_se": se, "rho_g": rho_g,
               "rho_l_mean": curves.mean(axis=0).tolist(),
               "rho_l_se": (curves.std(axis=0, ddof=1) / np.sqrt(len(curves))).tolist()
               if len(curves) > 1 else [None] * curves.shape[1],
               "simulations_mean": float(np.mean([t["simulations"] for t in found[m]])),
               "budget_sims_mean": float(np.mean([t["budget_sims"] for t in found[m]])),
               "time_s_mean": float(np.mean([t["time_s"] for t in found[m]])),
               "vectors": [t["vector"] for t in found[m]]}
        ours = [e["rho_g"] for e in evaluations.get("ours", [])]
        if ours and m != "ours" and len(rho_g) > 1:
            row["paired_vs_ours"] = _paired(rho_g, ours)
        if all(e.get("physics") for e in evaluations[m]):
            phys = [e["physics"]["rho_g"] for e in evaluations[m]]
            row["physics_rho_g"] = phys
            row["physics_rho_g_mean"], row["physics_rho_g_se"] = _mean_se(phys)
            row["physics_rho_l_mean"] = np.mean([e["physics"]["rho"] for e in evaluations[m]],
                                                axis=0).tolist()
            ours = [(e.get("physics") or {}).get("rho_g") for e in evaluations.get("ours", [])]
            if ours and None not in ours and m != "ours" and len(phys) > 1:
                row["physics_paired_vs_ours"] = _paired(phys, ours)
        rows.append(row)
    eps = evaluations[methods[0]][0]["eps"]
    return {"scenario": name, "budget_sims": budget, "seeds": seeds,
            "samples_per_radius": samples, "eps": eps, "rows": rows,
            "evaluation_power": _evaluation_power(evaluations, samples)}


def _paired(rho_g, ours) -> dict:
    """Mean difference (this method minus ours) with its s.e. and the paired t-test."""
    from scipy.stats import ttest_rel

    diff = np.asarray(rho_g) - np.asarray(ours)
    dm, dse = _mean_se(diff)
    p = float(ttest_rel(rho_g, ours).pvalue)
    return {"mean_difference": dm, "se": dse, "p_value": None if np.isnan(p) else p,
            "trials_for_0.05": _needed(float(diff.std(ddof=1)), 1)}


# two-sided 5 % test with 80 % power, normal approximation: z_0.975 + z_0.8
_Z_POWER = 1.959964 + 0.841621
DETECT = 0.05
"""The rho_g difference the power figures are for."""


def _needed(sd_one: float, per: float) -> int:
    """How many units (trials, or samples per radius) make a difference of ``DETECT``
    detectable, when ``per`` units give a spread ``sd_one`` of the difference."""
    return max(2, int(np.ceil(per * (_Z_POWER * sd_one / DETECT) ** 2)))


def _evaluation_power(evaluations: dict, samples: int) -> dict:
    """One layout's evaluation s.e. of rho_g (from the intervals), and the samples per radius
    that would let two layouts' evaluations alone separate ``DETECT``."""
    se = float(np.mean([(e["rho_g_interval"][1] - e["rho_g_interval"][0]) / (2 * 1.959964)
                        for es in evaluations.values() for e in es]))
    return {"rho_g_se": se, "samples_for_0.05": _needed(np.sqrt(2) * se, samples)}


def table_markdown(table: dict) -> str:
    """The table as Markdown, like the paper's Table 1."""
    def num(v, f="{:.3f}"):
        return "n/a" if v is None or (isinstance(v, float) and np.isnan(v)) else f.format(v)

    def diff(pair):
        if pair is None:
            return ""
        need = pair.get("trials_for_0.05")
        return (f"{pair['mean_difference']:+.3f} +- {num(pair['se'])} (p "
                f"{num(pair['p_value'], '{:.2g}')}" + (f"; {need} trials for 0.05)" if need
                                                        else ")"))

    phys = table.get("physics")
    lines = [f"# Benchmark: {table['scenario']}", "",
             f"B = {table['budget_sims']} simulations per method run (every simulation ours "
             f"ran, its final choice included; validity tests not counted); "
             f"{len(table['seeds'])} trial(s), seeds {table['seeds'][0]}.."
             f"{table['seeds'][-1]}; rho_l from {table['samples_per_radius']} valid layouts "
             "per radius, 30 radii, common random numbers across methods.", ""]
    if phys:
        lines += ["Placement + physics: the same layouts simulated with physical errors "
                  f"(friction +-{phys['friction']:.0%}, mass +-{phys['mass']:.0%}, "
                  f"restitution +-{phys['restitution']:.0%}), common draws across methods.", ""]
    head = "| method | trials | rho_g (mean +- s.e.) | paired diff. vs ours (p) | "
    rule = "|---|---|---|---|"
    if phys:
        head += "rho_g placement + physics | paired diff. vs ours (p) | "
        rule += "---|---|"
    lines += [head + "simulations used | time (s, one core) |", rule + "---|---|"]
    for r in table["rows"]:
        cells = f"| {r['label']} | {r['trials']} | {r['rho_g_mean']:.3f} +- " \
                f"{num(r['rho_g_se'])} | {diff(r.get('paired_vs_ours'))} | "
        if phys:
            cells += (f"{num(r.get('physics_rho_g_mean'))} +- {num(r.get('physics_rho_g_se'))}"
                      f" | {diff(r.get('physics_paired_vs_ours'))} | ")
        lines.append(cells + f"{r['simulations_mean']:.0f} | {r['time_s_mean']:.1f} |")
    power = table.get("evaluation_power")
    if power:
        lines += ["", f"Power for a difference of {DETECT} (two-sided 5 %, 80 % power, normal "
                  f"approximation): one layout's rho_g is estimated with s.e. "
                  f"{power['rho_g_se']:.3f} at {table['samples_per_radius']} layouts per "
                  f"radius, so two layouts {DETECT} apart are told apart by their evaluations "
                  f"with about {power['samples_for_0.05']} per radius; \"trials for "
                  f"{DETECT}\" is the number of seeds the paired test needs at the spread of "
                  "the differences observed."]
    return "\n".join(lines) + "\n"


def plot_benchmark(table: dict, path) -> None:
    """Mean rho_l curves with standard-error bands, one per method (like Fig. 15)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eps = np.asarray(table["eps"])
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    for r in table["rows"]:
        mean = np.asarray(r["rho_l_mean"])
        se = np.nan_to_num(np.asarray(r["rho_l_se"], dtype=float))
        (line,) = ax.plot(eps, mean, label=f"{r['label']} (rho_g {r['rho_g_mean']:.3f})")
        ax.fill_between(eps, mean - se, mean + se, color=line.get_color(), alpha=0.2, lw=0)
        if r.get("physics_rho_l_mean") is not None:
            ax.plot(eps, r["physics_rho_l_mean"], ls="--", color=line.get_color(),
                    label=f"  + physics (rho_g {r['physics_rho_g_mean']:.3f})")
    ax.set_xlabel("eps (radius in the normalised design space)")
    ax.set_ylabel("local robustness rho_l (mean over trials)")
    ax.set_xlim(0, float(eps.max()))
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(f"{table['scenario']}: B = {table['budget_sims']}, "
                 f"{len(table['seeds'])} trial(s)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
