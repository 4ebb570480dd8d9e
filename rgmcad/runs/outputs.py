"""What a finished ``optimize`` run writes (:func:`write_outputs`): ``layout.json`` (placement
tolerances in real units), ``start.json``, the report and its plots, and ``result.json`` last
(its presence marks the run finished)."""

from __future__ import annotations

import numpy as np

from rgmcad.files import write_atomic, write_json_atomic
from rgmcad.runs.hand_text import hand_note, plot_hand
from rgmcad.runs.report import (
    HAND_PLOT,
    PROGRESS_PLOT,
    REPORT_FILE,
    ROBUSTNESS_PLOT,
    SLICE_PLOT,
    plot_progress,
    plot_robustness,
    plot_slice,
    report_markdown,
)
from rgmcad.runs.store import MODEL, SETTINGS, SIMULATIONS
from rgmcad.runs.supports_text import read_supports, supports_lines
from rgmcad.runs.tolerance_check import BISECTIONS, POINTS, flags_of, pushed_against, sides_of
from rgmcad.sim.run import Outcome

__all__ = ["LAYOUT_FILE", "START_FILE", "at_layout", "influence", "write_outputs"]

LAYOUT_FILE = "layout.json"
START_FILE = "start.json"


def influence(model, x: np.ndarray) -> np.ndarray:
    """(d,) range of the predicted success along each axis through ``x`` (d,)."""
    t = np.linspace(0.0, 1.0, 101)
    out = np.zeros(len(x))
    for j in range(len(x)):
        P = np.repeat(x[None, :], len(t), axis=0)
        P[:, j] = t
        p = model.success_proba(P)
        out[j] = p.max() - p.min()
    return out


def at_layout(model, result, chosen: dict, x: np.ndarray, validity):
    """(per-event probabilities, probability, weakest requirement, its probability, (d, 2)
    normalised tolerances) at the chosen layout: the learner's own numbers at its optimum."""
    from rgmcad.learning import placement_tolerance

    if chosen["is_optimum"]:
        per_event, probability = dict(result.event_probabilities), result.probability
        tol = result.tolerances
    else:
        per_event = {e: float(p[0]) for e, p in model.event_probabilities(x).items()}
        probability = float(model.success_proba(x)[0])
        tol = placement_tolerance(model, x, result.settings, validity)
    weakest, weakest_probability = model.weakest_link(x)
    return per_event, probability, weakest, weakest_probability, tol


def write_outputs(scenario, store, recorded, result, chosen, wall_time, seed, budget,
                   robustness, starts, at_layout, checked, by_hand=None) -> dict:
    from rgmcad.learning import overlap_ends, range_ends
    from rgmcad.scene.design_space import bounds
    from rgmcad.scene.layout_files import layout_document

    run_dir = store.directory
    model = result.model
    x = np.asarray(chosen["x"], dtype=float)
    low, high = bounds(scenario)
    validity = recorded.problem.validity  # here, in this process: the pool is closed
    per_event, probability, weakest, weakest_probability, model_tol = at_layout
    tol = model_tol if checked is None else checked.tolerances

    def real(t):
        return {f.name: [float(t[j, 0] * (high[j] - low[j])), float(t[j, 1] * (high[j] - low[j]))]
                for j, f in enumerate(scenario.free)}

    tolerances = real(tol)
    narrowed = (np.zeros((len(x), 2), bool) if checked is None else checked.narrowed)
    check = None if checked is None else {
        "points_per_side": POINTS, "halvings": BISECTIONS, "simulations": checked.simulations,
        "narrowed": sides_of(narrowed, scenario), "model_tolerances": real(model_tol)}
    meet = flags_of(overlap_ends(x, model_tol, result.settings, validity)) & ~narrowed
    s = result.settings
    push = {} if checked is None else pushed_against(
        recorded.problem.context(), x, model_tol, meet,
        2.0 * s.tolerance_step / 2 ** s.tolerance_bisections)
    spread = influence(model, x)
    store.save_model(model)
    layout = write_json_atomic(run_dir / LAYOUT_FILE, layout_document(
        scenario, x, probability=probability, event_probabilities=per_event,
        weakest_event=weakest, tolerances=tolerances, source=chosen["source"],
        verified=chosen["verified"], push_against=push,
        **({"built_by_hand": hand_note(by_hand)} if by_hand else {})))
    start = write_json_atomic(run_dir / START_FILE, layout_document(
        scenario, result.x_start, probability=float(result.probability_start),
        source="the explored sample with the highest predicted success (start of the "
               "refinement)"))
    # what the run store holds: each distinct layout simulated once, verification included
    # (the learner's evaluations count a repeated vector, or a stored one, again)
    stored = list(store.records.values())
    n_success = sum(r.outcome is Outcome.SUCCESS for r in stored)
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
        "tolerance_check": check,
        # what stops a side the simulations kept: the range, or parts meeting
        "range_ends": sides_of(flags_of(range_ends(x, model_tol)) & ~narrowed, scenario),
        "overlap_ends": sides_of(meet, scenario),
        # a side that stops where parts meet, simulated at its bound: push the part there
        "push_against": push,
        "influence": {f.name: float(v) for f, v in zip(scenario.free, spread, strict=True)},
        "verified": chosen["verified"],
        "source": chosen["source"],
        "starts": {name: [float(u) for u in v] for name, v in (starts or {}).items()},
        "optimum": {"vector": [float(v) for v in result.x], "probability": result.probability,
                    "outcome": chosen["optimum_outcome"]},
        "start": {"layout": str(start), "vector": [float(v) for v in result.x_start],
                  "probability": float(result.probability_start)},
        "optimization": {"objective_start": result.optimization.objective_start,
                         "objective": result.optimization.objective,
                         "evaluations": result.optimization.n_evaluations,
                         "status": result.optimization.status},
        "simulations": len(stored),
        **({"worlds": len(recorded.physics_worlds)} if recorded.physics_worlds else {}),
        "evaluations": result.n_total_simulations + chosen["n_simulations"]
        + (checked.simulations if checked else 0) + (by_hand["simulations"] if by_hand else 0)
        + (chosen["hand_choice"]["simulations"] if "hand_choice" in chosen else 0),
        "simulations_by_stage": {**result.n_simulations, **chosen["by_stage"],
                                 **({"tolerance check": checked.simulations} if checked else {}),
                                 **({"choice by hand": chosen["hand_choice"]["simulations"]}
                                    if "hand_choice" in chosen else {}),
                                 **({"hand": by_hand["simulations"]} if by_hand else {})},
        "exploration": result.exploration_summary(),
        "verification": chosen["candidates"],
        **({"hand_choice": chosen["hand_choice"]} if "hand_choice" in chosen else {}),
        "centering": chosen["centering"], "second_look": chosen["second_look"],
        **{k: chosen[k] for k in ("more_looks", "close_in") if k in chosen},
        "verify_noise": result.settings.verify_noise, "error_radius": result.settings.error_radius,
        "race_stages": chosen["race_stages"], "verify_samples": result.settings.verify_samples,
        "robustness": robustness,
        "hand": by_hand,
        "successes": int(n_success),
        "discarded": result.n_discarded,
        "simulated_now": recorded.n_simulated,
        "replayed": max(len(stored) - recorded.n_simulated, 0),
        "simulation_seconds": float(sum(r.seconds for r in store.records.values())),
        "wall_time": wall_time,
        "factors": {e: _factor(scenario, result, e) for e in model.events},
        "seed": seed,
        "budget": budget,
        "model_sha256": store.model_sha256,
        "files": {"layout": LAYOUT_FILE, "start": START_FILE, "report": REPORT_FILE,
                  "slice_plot": SLICE_PLOT, "progress_plot": PROGRESS_PLOT,
                  "robustness_plot": ROBUSTNESS_PLOT, "model": MODEL,
                  **({"hand_plot": HAND_PLOT} if by_hand else {}),
                  "simulations": SIMULATIONS, "settings": SETTINGS},
    }
    plot_slice(scenario, model, x, spread, run_dir / SLICE_PLOT, validity)
    plot_robustness(scenario, model, x, run_dir / ROBUSTNESS_PLOT)
    plot_progress(result, run_dir / PROGRESS_PLOT)
    if by_hand:
        plot_hand(by_hand, run_dir / HAND_PLOT, f"{scenario.name}: the chosen layout, placed by "
                  "hand")
    write_atomic(run_dir / REPORT_FILE, report_markdown(
        scenario, summary, low, high, supports_lines(read_supports(run_dir))))
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
