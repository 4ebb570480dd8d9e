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

The user's own layouts (``references``, ``--reference``: a named layout of the scenario
such as ``solved``, or a layout file) are rows of their own: the same layout at every trial,
evaluated under that trial's draws, so paired with ours as the methods are (a hand layout
against the method, Table 1's question for a maker).

Everything is resumable: each method's trial and each evaluation is a run directory
(:class:`~rgmcad.runs.store.RunStore`: every simulation journaled, replayed on the next
call) under ``out/``, finished by a small ``trial.json``; the methods are deterministic given
their seed, so a benchmark killed at any point and run again gives the same table. Layout::

    out/ours/t{i}/              an ``rgmcad optimize`` run directory (out/full/t{i}: the
                                same with one global model, ``factorized=False``: Fig. 16)
    out/{method}-B{B}/t{i}/     a baseline's simulations and trial.json
    out/eval/{method}[-B{B}]/t{i}/   the evaluation of that trial's layout (the physical
                                draws are not journaled: an evaluation killed there redoes them)
    out/eval/layout-{NAME}-{digest}/t{i}/   a reference layout's evaluation at trial i
    out/benchmark.md, benchmark.json, robustness.png

The table holds every row the folder has finished under the call's protocol (scenario file,
budget, seeds, samples, physical errors), not only the methods asked for: a later call with
``--methods cma --budget-sims B`` adds CMA-ES's row to those an earlier call measured, paired
with ours' trials if they are there.

Times: ``time_s`` is the simulations' own seconds (from the journal, so a resumed trial
counts what its killed predecessor simulated) plus the method's computation outside the
simulations in the call that finished it: a cost on one core, independent of ``workers``.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rgmcad.files import write_atomic, write_json_atomic
from rgmcad.parts.family import family_digest
from rgmcad.runs.benchmark_table import build_table, plot_benchmark, table_markdown
from rgmcad.runs.checks import MAX_SAMPLES, MAX_SEED, check_range, check_workers
from rgmcad.runs.executor import make_executor, scheduler_from_env
from rgmcad.runs.problem import ScenarioProblem, scenario_digest, simulate_layout_task
from rgmcad.runs.starts import safe_name
from rgmcad.runs.store import RecordedProblem, RunStore, identity_differences, run_identity
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsRanges
from rgmcad.sim.revision import PHYSICS_REVISION

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
_REFERENCE = "--reference"
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
    simulation); validity tests are free, as for the baselines, and so is the check of the
    printed tolerances, which comes after the layout is chosen and never moves it."""
    checked = summary.get("simulations_by_stage", {}).get("tolerance check", 0)
    return int(summary.get("evaluations", summary["simulations"])) - int(checked)


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
        _check_same_settings(run_dir, settings)
        return done
    timed: list[_Timed] = []

    def recorded(*args):
        timed.append(_Timed(*args))
        return timed[-1]

    start = time.perf_counter()
    run = optimize_scenario(scenario_path, seed=seed, budget=budget, settings=settings,
                            run_dir=run_dir, workers=workers, build_dir=build_dir,
                            progress=progress, recorded=recorded, scheduler=scheduler,
                            parts_dir=parts_dir, tolerance_check=False,  # the table needs none
                            hand=None)  # Table 1: the paper's protocol, rho_g
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


def _finished_ours(out: Path, seeds: Sequence[int], digest: str) -> list[dict] | None:
    """Ours' trials an earlier call finished in ``out`` for every seed of this scenario file,
    or None."""
    trials = []
    for s in seeds:
        trial = _read(out / "ours" / f"t{s}" / TRIAL)
        ident = _read(out / "ours" / f"t{s}" / "settings.json") or {}
        if trial is None or trial.get("seed") != s or ident.get("scenario_sha256") != digest:
            return None
        trials.append(trial)
    return trials


def _earlier_rows(out: Path, base: dict, budget: int, seeds: Sequence[int], samples: int,
                  physics: PhysicsRanges | None, skip) -> dict[str, tuple]:
    """Rows an earlier call left finished in ``out`` under this call's protocol (the same
    scenario file, budget, seeds, samples per radius and physical errors), so that running
    one more method adds a row instead of replacing the table: method name, or a layout's
    folder tag, -> (label, trials, evaluations, layout name or None). A method or layout is
    taken only when every seed's trial and evaluation are finished and their identities
    match; anything else is left out, never run."""
    wanted = None if physics is None else physics.to_json()
    tags = [m if m in LEARNERS else f"{m}-B{budget}" for m in METHODS]
    layouts = sorted(p.name for p in (out / "eval").glob("layout-*") if p.is_dir())
    rows: dict[str, tuple] = {}
    for tag in (*tags, *layouts):
        layout = tag.startswith("layout-")
        method = tag if layout else tag.split("-B")[0]
        if method in skip:
            continue
        trials, evals = [], []
        for s in seeds:
            if layout:
                trial = {"method": tag, "seed": s, "budget_sims": None, "simulations": None,
                         "time_s": None}
            else:
                trial = _read(out / tag / f"t{s}" / TRIAL)
                if trial is None or trial.get("seed") != s:
                    break  # the evaluation's identity below checks the scenario and parts
            run = out / "eval" / tag / f"t{s}"
            done, ident = _read(run / TRIAL), _read(run / "settings.json")
            trial.setdefault("vector", (done or {}).get("vector"))
            expected = {**base, "kind": "evaluation", "vector": trial["vector"], "seed": s,
                        "samples": samples}
            if (done is None or ident != json.loads(json.dumps(expected))
                    or wanted not in (None, (done.get("physics") or {}).get("ranges"))):
                break
            trials.append(trial)
            evals.append(done)
        else:
            name = tag[len("layout-"):-9] if layout else None  # layout-NAME-DIGEST8
            label = LABELS[method] if name is None else f"layout {name!r}"
            rows[method] = (label, trials, evals, name)
    return rows


def _references(scenario, problem, layouts: Sequence[str]) -> dict[str, np.ndarray]:
    """Name -> vector of each ``--reference`` layout, refused in one line when unknown,
    unreadable, outside the free ranges or overlapping."""
    from rgmcad.runs.starts import check_starts_valid, resolve_starts

    given = resolve_starts(scenario, layouts, _REFERENCE)
    check_starts_valid(problem, given, _REFERENCE)
    return given


def _check_same_settings(run_dir: Path, settings) -> None:
    """A finished trial of ours is reused only if it learned with ``settings``."""
    from rgmcad.errors import RunDirectoryError

    stored = (_read(run_dir / "settings.json") or {}).get("settings")
    diffs = [] if stored is None else identity_differences(
        stored, run_identity("", "", 0, settings)["settings"], "settings.")
    if diffs:
        key, had, asked = diffs[0]
        raise RunDirectoryError(str(run_dir / "settings.json"), key,
                                f"this trial of ours learned with {had!r}, the command asks "
                                f"{asked!r}; give the benchmark another --out")


def run_benchmark(scenario_path, out_dir, *, methods=DEFAULT_METHODS, trials: int = 10,
                  seed: int = 0, budget_sims: int | None = None, samples: int = 50,
                  ours_budget: str = "default", ours_settings=None,
                  workers: int | None = None, build_dir=None, progress=None,
                  scheduler: str | None = None, parts_dir=None,
                  physics: PhysicsRanges | None = DEFAULT_PHYSICS,
                  references: Sequence[str] = ()) -> dict:
    """Run (or continue) a benchmark and write its table and figure; returns the table
    (what ``benchmark.json`` holds). See the module docstring. ``scheduler``: a Dask
    scheduler's address or ``local:N`` (None: ``RGMCAD_SCHEDULER`` if set, else ``workers``
    processes); ``parts_dir``: the user's part families (``--parts``); ``physics``: the
    physical errors of the second rho_g (None: placement errors only); ``references``: the
    user's layouts (``--reference``: named layouts of the scenario or layout files), each a
    row of its own, evaluated under every trial's draws like the methods' layouts."""
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
    scenario = load_scenario(scenario_path, parts_dir=parts_dir)
    digest = scenario_digest(scenario_path)
    seeds = [seed + i for i in range(trials)]
    ours_before = None if "ours" in methods else _finished_ours(Path(out_dir), seeds, digest)
    if budget_sims is None and "ours" not in methods and ours_before is None:
        raise UsageError("--budget-sims", "", "needed when ours is not among --methods and "
                         "has not finished these trials in --out (the budget is otherwise the "
                         "mean number of simulations ours used)")
    problem = ScenarioProblem(scenario_path, build_dir, parts_dir)
    given = _references(scenario, problem, references)  # refused before any folder
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    found: dict[str, list[dict]] = {}
    for m in (m for m in methods if m in LEARNERS):
        for s in seeds:
            progress.stage(f"{m} t{s}")
            found.setdefault(m, []).append(_ours(
                m, scenario_path, out, s, ours_budget, ours_settings, workers, build_dir,
                progress, scheduler, parts_dir))
    budget = budget_sims if budget_sims is not None else int(
        np.floor(np.mean([t["budget_sims"] for t in found.get("ours", ours_before)])))
    executor = make_executor(workers, problem.context, scheduler=scheduler_from_env(scheduler),
                             payload=problem.payload)
    base = {"format": 1, "scenario": scenario.name, "scenario_sha256": digest}
    if parts_dir is not None:  # other families, other results: not the same trials
        base["parts"] = {n: family_digest(f) for n, f in sorted(scenario.families.items())}
    tags = {m: m if m in LEARNERS else f"{m}-B{budget}" for m in methods}
    labels = dict(LABELS)
    for name, x in given.items():  # the same layout at every trial, nothing spent on it
        tag = f"layout-{safe_name(name)}-{hashlib.sha256(x.tobytes()).hexdigest()[:8]}"
        tags[tag], labels[tag] = tag, f"layout {name!r}"
        found[tag] = [{"method": tag, "seed": s, "vector": [float(v) for v in x],
                       "budget_sims": None, "simulations": None, "time_s": None}
                      for s in seeds]
    refs = tuple(t for t in tags if t not in methods)
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
        for m in (*methods, *refs):
            for s, trial in zip(seeds, found[m], strict=True):
                progress.stage(f"evaluate {m} t{s}")
                identity = {**base, "kind": "evaluation", "vector": trial["vector"],
                            "seed": s, "samples": samples}
                evaluations.setdefault(m, []).append(evaluate_trial(
                    identity, out / "eval" / tags[m] / f"t{s}", problem, executor,
                    trial["vector"], samples, s, progress, physics))
    finally:
        executor.close()
    earlier = _earlier_rows(out, base, budget, seeds, samples, physics,
                            skip={*methods, *refs})
    for tag, (label, trials, evals, _) in earlier.items():
        labels[tag], found[tag], evaluations[tag] = label, trials, evals
    more_methods = tuple(t for t, row in earlier.items() if row[3] is None)
    more_layouts = {row[3]: t for t, row in earlier.items() if row[3] is not None}
    rows = (*sorted((*methods, *more_methods), key=METHODS.index), *refs,
            *more_layouts.values())
    table = build_table(scenario.name, rows, labels, seeds, budget, samples, found,
                        evaluations)
    table["references"] = {name: [float(v) for v in x] for name, x in given.items()}
    table["references"].update({n: found[t][0]["vector"] for n, t in more_layouts.items()})
    table["earlier_rows"] = [labels[t] for t in earlier]
    table["physics"] = None if physics is None else physics.to_json()
    table["wall_time"] = time.perf_counter() - start
    table["physics_revision"] = PHYSICS_REVISION
    write_json_atomic(out / TABLE_JSON, table)
    write_atomic(out / TABLE_MD, table_markdown(table))
    plot_benchmark(table, out / PLOT)
    return table
