"""``rgmcad optimize`` and ``rgmcad evaluate``: the commands around the learning pipeline.

``optimize`` learns the success probability of a scenario's design space and refines the
most robust layout (paper sections 5-7) in a run directory that survives interruptions
(:mod:`rgmcad.runs.store`); ``evaluate`` measures a layout's local and global robustness by
simulation (:mod:`rgmcad.runs.robustness`). Both spread simulations over a process pool
(:mod:`rgmcad.runs.executor`). :data:`rgmcad.cli.COMMANDS` wires them in.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

__all__ = ["BUDGETS", "budget", "configure_optimize", "cmd_optimize", "configure_evaluate",
           "cmd_evaluate"]

BUDGETS = ("default", "small")
"""Names of the settings of ``--budget`` (see :func:`budget`)."""


def budget(name: str):
    """The :class:`~rgmcad.learning.LearningSettings` of a ``--budget`` name.

    ``default`` is the settings behind the paper's Table 1 (SPEC 5.7; every default of
    ``LearningSettings`` is documented there). ``small`` is a quick look for trying a scenario
    out and for tests, not for results: N0 = 100 Sobol points, N+ = 20, at most 50
    exploration and 2 active-learning iterations, a 4 x 4 SVM grid, 16 placement errors,
    8 errors per candidate in the final choice.
    """
    from rgmcad.learning import LearningSettings

    if name == "default":
        return LearningSettings()
    if name == "small":
        return LearningSettings(
            n_initial=100, n_successes=20, exploration_max_iter=50, active_batch=10,
            active_max_iter=2, svm_C_grid=(0.1, 1.0, 10.0, 100.0),
            svm_gamma_grid=(0.1, 1.0, 10.0, 100.0), placement_samples=16,
            optimizer_max_eval=200, verify_samples=8,
        )
    raise ValueError(f"unknown budget {name!r}; valid: {', '.join(BUDGETS)}")

LAYOUT_FILE = "layout.json"
START_FILE = "start.json"
REPORT_FILE = "report.md"
SLICE_PLOT = "probability_slice.png"
PROGRESS_PLOT = "exploration.png"


def _out(text: str = "") -> None:
    sys.stdout.write(text + "\n")


# --- shared -----------------------------------------------------------------------------------


def _scenario(args):
    from rgmcad.scene.loader import load_scenario

    return load_scenario(args.scenario)


def _problem_and_executor(args):
    from rgmcad.runs.executor import make_executor
    from rgmcad.runs.problem import ScenarioProblem, context

    if not Path(args.build_dir).exists():
        sys.stderr.write(f"building parts into {args.build_dir} (first run only)...\n")
    problem = ScenarioProblem(args.scenario, args.build_dir)
    executor = make_executor(args.workers, context, (problem.scenario_path, problem.build_dir))
    return problem, executor


def _write_json(path: Path, data) -> Path:
    path.write_text(json.dumps(data, indent=1) + "\n")
    return path


# --- optimize -----------------------------------------------------------------------------------


def configure_optimize(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="scenario file (TOML), e.g. scenarios/simple.toml")
    p.add_argument("--run", dest="run_dir", metavar="DIR", help="run directory (default: "
                   "runs/SCENARIO-sSEED, runs/SCENARIO-small-sSEED for --budget small); the "
                   "same command on the same DIR continues an interrupted run")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="simulation processes (default: every CPU); results do not depend on it")
    p.add_argument("--budget", choices=BUDGETS, default="default",
                   help="default: the paper's Table 1 settings; small: a quick look")
    p.add_argument("--json", action="store_true", help="print one JSON summary on stdout")


def _default_run_dir(scenario, args) -> Path:
    budget = "" if args.budget == "default" else f"-{args.budget}"
    return Path("runs") / f"{scenario.name}{budget}-s{args.seed}"


class _Bar:
    """Progress on stderr: stage, simulations (new and replayed), successes."""

    def __init__(self):
        from tqdm import tqdm

        self.bar = tqdm(desc="exploration", unit="sim", file=sys.stderr, mininterval=0.5,
                        dynamic_ncols=True)
        self.successes = self.replayed = 0

    def simulation(self, record, replayed: bool) -> None:
        self.successes += record.outcome == "success"
        self.replayed += replayed
        self.bar.set_postfix(successes=self.successes, replayed=self.replayed, refresh=False)
        self.bar.update(1)

    def progress(self, progress) -> None:
        """``on_progress`` of the learner."""
        self.stage(progress.stage)

    def stage(self, name: str) -> None:
        if name != self.bar.desc:
            self.bar.set_description(name)

    def close(self) -> None:
        self.bar.close()


def cmd_optimize(args) -> int:
    start = time.perf_counter()
    from rgmcad.runs.problem import scenario_digest
    from rgmcad.runs.store import RecordedProblem, RunStore, run_identity

    scenario = _scenario(args)
    settings = budget(args.budget)
    identity = run_identity(scenario.name, scenario_digest(args.scenario), args.seed, settings)
    run_dir = Path(args.run_dir) if args.run_dir else _default_run_dir(scenario, args)
    with RunStore(run_dir, identity) as store:
        if store.finished and (run_dir / LAYOUT_FILE).exists():
            summary = store.read_result()
            sys.stderr.write(f"{run_dir}: finished already; showing its result\n")
            _print_summary(summary, args.json, wall_time=time.perf_counter() - start)
            return 0 if summary["verified"] else 1
        from rgmcad.learning import learn_and_optimize
        from rgmcad.learning.parallel import jobs_on

        problem, executor = _problem_and_executor(args)
        bar = _Bar()
        try:
            recorded = RecordedProblem(problem, store, executor, bar.simulation)
            # The pool is idle while the models train: their grid searches, calibration folds
            # and mutual information estimates run there (never changing the result).
            with jobs_on(executor):
                result = learn_and_optimize(recorded, settings, args.seed,
                                            on_progress=bar.progress)
            bar.stage("verification")
            chosen = _verify(recorded, result)
        finally:
            bar.close()
            executor.close()
        summary = _write_outputs(scenario, args, store, recorded, result, chosen,
                                 time.perf_counter() - start)
    _print_summary(summary, args.json)
    return 0 if chosen["verified"] else 1


def _verify(recorded, result) -> dict:
    """The layout to hand out: see :mod:`rgmcad.learning.verify`."""
    from rgmcad.learning import verify_layout

    v = verify_layout(result.model, result.x, result.X, result.labels, recorded.simulate,
                      recorded.validity, result.settings)
    c = v.chosen
    if not v.verified:
        source = (f"optimum, unverified: its simulation gave {v.optimum.outcome} and no "
                  "simulated layout succeeded")
    elif c.source == "optimum":
        source = "optimum"
    elif v.optimum.outcome != "success":
        source = f"{c.source} (the optimum's simulation gave {v.optimum.outcome})"
    else:
        source = f"{c.source} (more robust than the optimum under placement errors)"
    return {"x": c.x, "source": source, "verified": v.verified,
            "optimum_outcome": v.optimum.outcome, "n_simulations": v.n_simulations,
            "candidates": [{"source": t.source, "vector": [float(u) for u in t.x],
                            "success_rate": t.success_rate, "valid_copies": t.n_valid}
                           for t in v.candidates]}


def _influence(model, x: np.ndarray) -> np.ndarray:
    """(d,) range of the predicted success along each axis through ``x``."""
    t = np.linspace(0.0, 1.0, 101)
    out = np.zeros(len(x))
    for j in range(len(x)):
        P = np.repeat(x[None, :], len(t), axis=0)
        P[:, j] = t
        p = model.success_proba(P)
        out[j] = p.max() - p.min()
    return out


def _write_outputs(scenario, args, store, recorded, result, chosen, wall_time) -> dict:
    from rgmcad.learning import placement_tolerance
    from rgmcad.scene.design_space import bounds

    run_dir = store.directory
    model = result.model
    x = np.asarray(chosen["x"], dtype=float)
    low, high = bounds(scenario)
    per_event = {e: float(p[0]) for e, p in model.event_probabilities(x).items()}
    probability = float(model.success_proba(x)[0])
    weakest, weakest_probability = model.weakest_link(x)
    tol = placement_tolerance(model, x, result.settings) if chosen["source"] != "optimum" \
        else result.tolerances  # the chosen layout may not be the optimum
    tolerances = {f.name: [float(tol[j, 0] * (high[j] - low[j])),
                           float(tol[j, 1] * (high[j] - low[j]))]
                  for j, f in enumerate(scenario.free)}
    from rgmcad.scene.layout_files import layout_document

    influence = _influence(model, x)
    store.save_model(model)
    layout = _write_json(run_dir / LAYOUT_FILE, layout_document(
        scenario, x, probability=probability, event_probabilities=per_event,
        weakest_event=weakest, tolerances=tolerances, source=chosen["source"],
        verified=chosen["verified"]))
    start = _write_json(run_dir / START_FILE, layout_document(
        scenario, result.x_start, probability=float(result.probability_start),
        source="the explored sample with the highest predicted success (start of the "
               "refinement)"))
    n_total = result.n_total_simulations + chosen["n_simulations"]
    n_success = sum(lab.success for lab in result.labels)
    summary = {
        "scenario": scenario.name,
        "run": str(run_dir),
        "layout": str(layout),
        "vector": [float(v) for v in x],
        "values": {f.name: float(v) for f, v in zip(scenario.free, low + x * (high - low),
                                                     strict=True)},
        "probability": probability,
        "event_probabilities": per_event,
        "weakest_event": weakest,
        "weakest_probability": weakest_probability,
        "tolerances": tolerances,
        "influence": {f.name: float(v) for f, v in zip(scenario.free, influence, strict=True)},
        "verified": chosen["verified"],
        "source": chosen["source"],
        "optimum": {"vector": [float(v) for v in result.x], "probability": result.probability,
                    "outcome": chosen["optimum_outcome"]},
        "start": {"layout": str(start), "vector": [float(v) for v in result.x_start],
                  "probability": float(result.probability_start)},
        "optimization": {"objective_start": result.optimization.objective_start,
                         "objective": result.optimization.objective,
                         "evaluations": result.optimization.n_evaluations,
                         "status": result.optimization.status},
        "simulations": n_total,
        "simulations_by_stage": {**result.n_simulations,
                                 "verification": chosen["n_simulations"]},
        "verification": chosen["candidates"],
        "verify_noise": result.settings.verify_noise,
        "successes": int(n_success),
        "discarded": result.n_discarded,
        "simulated_now": recorded.n_simulated,
        "replayed": recorded.n_replayed,
        "simulation_seconds": float(sum(r.seconds for r in store.records.values())),
        "wall_time": wall_time,
        "factors": {e: _factor(scenario, result, e) for e in model.events},
        "seed": args.seed,
        "budget": args.budget,
        "files": {"layout": LAYOUT_FILE, "start": START_FILE, "report": REPORT_FILE,
                  "slice_plot": SLICE_PLOT, "progress_plot": PROGRESS_PLOT, "model": "model.pkl",
                  "simulations": "simulations.jsonl", "settings": "settings.json"},
    }
    _plot_slice(scenario, model, x, influence, run_dir / SLICE_PLOT)
    _plot_progress(result, run_dir / PROGRESS_PLOT)
    (run_dir / REPORT_FILE).write_text(_report(scenario, summary, low, high))
    store.write_result(summary)  # last: its presence marks the run finished
    return summary


def _factor(scenario, result, event) -> dict:
    m = result.model.models[event]
    names = [f.name for f in scenario.free]
    out = {"model": getattr(m, "reason", None) or "svm",
           "dims": [names[j] for j in m.dims_] if not m.is_constant else []}
    a = result.analyses.get(event)
    if a is not None:
        out.update(samples=a.n_samples, success_rate=None if np.isnan(a.success_rate)
                   else a.success_rate, quasi_deterministic=a.quasi_deterministic)
    if event in result.accuracy:
        out["accuracy"] = [float(v) for v in result.accuracy[event]]
    return out


def _print_summary(summary: dict, as_json: bool, wall_time: float | None = None) -> None:
    if as_json:
        out = dict(summary)
        if wall_time is not None:
            out["wall_time_this_call"] = wall_time
        _out(json.dumps(out))
        return
    weakest = summary["weakest_event"]
    _out(f"{summary['scenario']}: {summary['layout']}")
    _out(f"predicted P(success) {summary['probability']:.3f}, weakest link {weakest} "
         f"({summary.get('weakest_probability', summary['event_probabilities'].get(weakest, 1.0)):.3f}"
         f"); {summary['source']}")
    _out(f"{summary['simulations']} simulations ({summary['successes']} successes, "
         f"{summary['replayed']} replayed) in {summary['wall_time']:.0f} s")
    _out("placement tolerances (down / up):")
    for name, (down, up) in summary["tolerances"].items():
        unit = "deg" if name.split(".")[-1] in ("heading", "pitch", "roll") else "mm"
        k = 1.0 if unit == "deg" else 1000.0
        _out(f"  {name:24s} {summary['values'][name] * k:9.2f} {unit:3s}  "
             f"-{down * k:.2f} / +{up * k:.2f}")
    _out(f"report: {Path(summary['run']) / REPORT_FILE}")


def _report(scenario, s: dict, low, high) -> str:
    lines = [f"# {scenario.name}: optimised layout", "",
             f"- run: `{s['run']}` (seed {s['seed']}, budget {s['budget']})",
             f"- layout file: `{s['layout']}` (`--layout` of every command)",
             f"- predicted success probability: **{s['probability']:.3f}**; weakest link: "
             f"`{s['weakest_event']}`",
             f"- chosen layout: {s['source']}; verified by simulation: "
             f"{'yes' if s['verified'] else 'NO'}",
             f"- simulations: {s['simulations']} ({s['successes']} successes; by stage: "
             + ", ".join(f"{k} {v}" for k, v in s["simulations_by_stage"].items()) + ")",
             f"- wall time: {s['wall_time']:.0f} s (simulation {s['simulation_seconds']:.0f} "
             "s of CPU)",
             f"- refinement: objective {s['optimization']['objective_start']:.3f} -> "
             f"{s['optimization']['objective']:.3f} ({s['optimization']['evaluations']} "
             f"evaluations, {s['optimization']['status']})", "",
             "## Per-event probability at the layout", "",
             "| event | P(success given parents) | model | parameters |", "|---|---|---|---|"]
    for e, p in s["event_probabilities"].items():
        f = s["factors"].get(e, {})
        mark = " (weakest)" if e == s["weakest_event"] else ""
        lines.append(f"| {e}{mark} | {p:.3f} | {f.get('model', '')} | "
                     f"{', '.join(f.get('dims', [])) or '-'} |")
    lines += ["", "## Placement", "",
              "How far each parameter may move, alone, before the predicted success drops "
              "below 90 % of its value here (the parameter's whole range is shown for scale).",
              "", "| parameter | value | may move down | may move up | range |",
              "|---|---|---|---|---|"]
    for j, f in enumerate(scenario.free):
        k, unit = (1.0, "deg") if f.unit == "deg" else (1000.0, "mm")
        down, up = s["tolerances"][f.name]
        lines.append(f"| {f.name} | {s['values'][f.name] * k:.2f} {unit} | {down * k:.2f} | "
                     f"{up * k:.2f} | [{low[j] * k:.2f}, {high[j] * k:.2f}] |")
    if s.get("verification"):
        lines += ["", "## Choice of the layout", "",
                  "Each candidate succeeded in simulation; then it was simulated at placement "
                  "errors (Gaussian, standard deviation "
                  f"{s['verify_noise']:g} of each range) and the one that succeeded most often "
                  "was kept.", "", "| candidate | success under errors | valid copies |",
                  "|---|---|---|"]
        for c in s["verification"]:
            lines.append(f"| {c['source']} | {c['success_rate']:.2f} | {c['valid_copies']} |")
    lines += ["", "## Plots", "", f"![probability slice]({SLICE_PLOT})", "",
              f"![exploration]({PROGRESS_PLOT})", ""]
    return "\n".join(lines)


def _plot_slice(scenario, model, x, influence, path: Path) -> None:
    """Predicted success through ``x`` along its two most influential parameters."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rgmcad.scene.design_space import bounds

    low, high = bounds(scenario)
    order = np.argsort(-influence, kind="stable")
    fig, ax = plt.subplots(figsize=(5.5, 4.5), dpi=120)
    t = np.linspace(0.0, 1.0, 81)
    if len(x) == 1:
        P = t[:, None]
        ax.plot(low[0] + t * (high[0] - low[0]), model.success_proba(P))
        ax.axvline(low[0] + x[0] * (high[0] - low[0]), color="k", ls="--")
        ax.set_xlabel(scenario.free[0].name)
        ax.set_ylabel("P(success)")
    else:
        i, j = (int(v) for v in order[:2])
        A, B = np.meshgrid(t, t)
        P = np.repeat(x[None, :], A.size, axis=0)
        P[:, i], P[:, j] = A.ravel(), B.ravel()
        Z = model.success_proba(P).reshape(A.shape)
        ext = [low[i], high[i], low[j], high[j]]
        im = ax.imshow(Z, origin="lower", extent=ext, aspect="auto", vmin=0, vmax=1,
                       cmap="viridis")
        ax.contour(low[i] + A * (high[i] - low[i]), low[j] + B * (high[j] - low[j]), Z,
                   levels=[0.5, 0.9], colors="w", linewidths=0.8)
        ax.plot(low[i] + x[i] * (high[i] - low[i]), low[j] + x[j] * (high[j] - low[j]),
                "r*", ms=12, label="layout")
        fi, fj = scenario.free[i], scenario.free[j]
        ax.set_xlabel(f"{fi.name} ({fi.unit})")
        ax.set_ylabel(f"{fj.name} ({fj.unit})")
        fig.colorbar(im, ax=ax, label="predicted P(success)")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"{scenario.name}: slice through the layout", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _plot_progress(result, path: Path) -> None:
    """Successful events per simulation (by stage) and cumulative global successes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_events = np.array([lab.n_success for lab in result.labels])
    success = np.array([lab.success for lab in result.labels])
    stages = np.array(result.stages)
    idx = np.arange(len(n_events))
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(7, 5), dpi=120, sharex=True)
    for st in dict.fromkeys(stages):
        m = stages == st
        ax1.scatter(idx[m], n_events[m], s=4, label=st)
    ax1.set_ylabel("successful events")
    ax1.legend(fontsize=7, markerscale=3, loc="lower right")
    ax2.plot(idx, np.cumsum(success), color="k")
    ax2.set_ylabel("global successes")
    ax2.set_xlabel("simulation")
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    fig.suptitle("exploration and active learning", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


# --- evaluate -----------------------------------------------------------------------------------


def configure_evaluate(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="scenario file (TOML), e.g. scenarios/simple.toml")
    p.add_argument("--layout", required=True, help="a named layout of the scenario or a layout "
                   "file (e.g. runs/simple-s0/layout.json)")
    p.add_argument("--samples", type=int, default=50, help="valid layouts simulated per radius "
                   "(default 50; 30 radii, so 1500 simulations)")
    p.add_argument("--seed", type=int, default=0, help="seed of the sampling (default 0)")
    p.add_argument("--workers", type=int, default=None,
                   help="simulation processes (default: every CPU); results do not depend on it")
    p.add_argument("--out", metavar="FILE.png", help="the plot (default: next to a layout file, "
                   "or robustness-SCENARIO-LAYOUT.png here)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def cmd_evaluate(args) -> int:
    from tqdm import tqdm

    from rgmcad.errors import UsageError
    from rgmcad.runs.executor import map_blocks
    from rgmcad.runs.robustness import local_robustness, plot_curves
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.layout_files import resolve_layout

    if args.samples < 1:
        raise UsageError("--samples", "", "expected a positive number of layouts per radius")
    scenario = _scenario(args)
    name, values = resolve_layout(scenario, args.layout, None)
    x = vector_from_values(scenario, values)
    if args.out:
        out = Path(args.out)
    elif Path(args.layout).is_file():
        out = Path(args.layout).with_name(f"{Path(args.layout).stem}-robustness.png")
    else:
        out = Path(f"robustness-{scenario.name}-{name}.png")
    start = time.perf_counter()
    problem, executor = _problem_and_executor(args)
    bar = tqdm(desc="validity", unit="layout", file=sys.stderr, mininterval=0.5)

    def validity(X):
        ok = map_blocks(executor, problem.validity, X)
        bar.update(len(X))
        return ok

    def simulate(X):
        bar.set_description("simulation")
        bar.reset(total=len(X))
        out = []
        for r in executor.map(problem.simulate_one, list(X)):
            out.append(r)
            bar.update(1)
        return out

    try:
        curve = local_robustness(x, validity, simulate, args.samples, args.seed)
    finally:
        bar.close()
        executor.close()
    wall = time.perf_counter() - start
    plot_curves({name: curve}, out, title=f"{scenario.name}: local robustness of {name}")
    result = {
        "scenario": scenario.name, "layout": name, "vector": [float(v) for v in x],
        "rho_g": curve.rho_g, "rho_g_interval": [curve.rho_g_low, curve.rho_g_high],
        "curve": curve.curve(), "counts": [int(c) for c in curve.counts],
        "simulations": curve.simulations, "validity_tests": curve.validity_tests,
        "samples_per_radius": args.samples, "eta": curve.eta, "seed": args.seed,
        "wall_time": wall, "plot": str(out),
    }
    if args.json:
        _out(json.dumps(result))
        return 0
    _out(f"{scenario.name}, layout {name}: rho_g = {curve.rho_g:.3f} "
         f"[{curve.rho_g_low:.3f}, {curve.rho_g_high:.3f}] from {curve.simulations} simulations "
         f"in {wall:.0f} s")
    _out("eps     rho_l   95 % interval")
    for e, r, lo, hi in curve.curve()[::3]:
        _out(f"{e:5.3f}   {r:5.3f}   [{lo:.3f}, {hi:.3f}]")
    _out(f"plot: {out}")
    return 0
