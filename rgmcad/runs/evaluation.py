"""The workflow behind ``rgmcad evaluate``: how often a layout works when a person builds it
(:mod:`rgmcad.runs.hand`: a hand's errors in millimetres and degrees, the curve against their
size, the weak links), or, as Table 1 measures it, its local and global robustness in the
normalised design space (:mod:`rgmcad.runs.robustness`); and the plot. The simulations are
spread over a process pool (:mod:`rgmcad.runs.executor`), progress reported to a
:class:`~rgmcad.runs.workflow.RunProgress`; it does not print."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

from rgmcad.errors import UsageError
from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.checks import MAX_SAMPLES, MAX_SEED, check_plot_file, check_range, check_workers
from rgmcad.runs.executor import make_executor, map_blocks, scheduler_from_env
from rgmcad.runs.hand import (
    DEFAULT_HAND,
    HAND_SETTINGS,
    Hand,
    check_precision,
    hand_figures,
)
from rgmcad.runs.hand_text import plot_hand
from rgmcad.runs.problem import ScenarioProblem, validity_task
from rgmcad.runs.workflow import RunProgress
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsRanges

__all__ = ["evaluate_layout", "MEASURES"]

MEASURES = ("hand", "rho_g")


def evaluate_layout(
    scenario_path: str | Path, layout: str, *, samples: int = 50, seed: int = 0,
    workers: int | None = None, build_dir: str | Path = DEFAULT_BUILD_DIR,
    plot: str | Path | None = None, progress: RunProgress | None = None,
    parts_dir: str | Path | None = None, scheduler: str | None = None,
    physics: PhysicsRanges | None = DEFAULT_PHYSICS, measure: str = "hand",
    hand: Hand = DEFAULT_HAND, precision: float = 0.05,
) -> dict:
    """How robust a layout is, by simulation, and the plot.

    ``measure="hand"`` (default): :func:`hand_figures`, the success rate when a person places
    every part within ``hand``'s errors with ``physics``' errors on top, to ``precision``
    (half-width of the 95 % interval), the curve against the hand's size and the weak links.
    ``measure="rho_g"``: local robustness at every radius and global robustness rho_g
    (:func:`~rgmcad.runs.robustness.local_robustness`, Table 1's measure); with ``physics``
    (default: :data:`~rgmcad.scene.perturbation.DEFAULT_PHYSICS`; None: placement only),
    also under placement plus physical errors, on the same layouts.

    Parameters
    ----------
    layout : a named layout of the scenario or a layout file.
    samples : (rho_g) valid layouts simulated per radius, 1..100 000.
    plot : the PNG (or any matplotlib format) to write, checked before the simulations;
        default: beside a layout file, else
        ``robustness-SCENARIO-LAYOUT.png`` in the working directory.
    parts_dir : a folder of the user's part families (``--parts``; None: the shipped ones).
    scheduler : a Dask scheduler's address or ``local:N`` (None: ``RGMCAD_SCHEDULER`` if set,
        else local processes).

    Returns
    -------
    dict
        What ``rgmcad evaluate --json`` prints.
    """
    from rgmcad.runs.robustness import figures, plot_curves, robustness_on
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.layout_files import resolve_layout
    from rgmcad.scene.loader import load_scenario

    progress = progress or RunProgress()
    if measure not in MEASURES:
        raise UsageError("measure", repr(measure), f"expected one of {', '.join(MEASURES)}")
    check_range(samples, 1, MAX_SAMPLES, "samples", "a number of layouts per radius")
    check_precision(precision, "precision")
    check_range(seed, 0, MAX_SEED, "seed", "a seed")
    check_workers(workers, "workers")
    scenario = load_scenario(scenario_path, parts_dir=parts_dir)
    name, values = resolve_layout(scenario, layout, None)
    x = vector_from_values(scenario, values)
    if plot is None:
        stem = "hand" if measure == "hand" else "robustness"
        plot = (Path(layout).with_name(f"{Path(layout).stem}-{stem}.png")
                if Path(layout).is_file() else Path(f"{stem}-{scenario.name}-{name}.png"))
    check_plot_file(plot, "plot")  # before the simulations, not after
    start = time.perf_counter()
    problem = ScenarioProblem(scenario_path, build_dir, parts_dir)
    executor = make_executor(workers, problem.context, scheduler=scheduler_from_env(scheduler),
                             payload=problem.payload)
    common = {"scenario": scenario.name, "layout": name, "vector": [float(v) for v in x],
              "seed": seed, "plot": str(plot)}
    if measure == "hand":
        try:
            settings = dataclasses.replace(HAND_SETTINGS["default"], precision=precision)
            figures_ = hand_figures(executor, problem, x, hand, physics, seed, settings,
                                    progress, name)
        finally:
            executor.close()
        plot_hand(figures_, plot, f"{scenario.name}: layout {name} placed by hand")
        return {**common, **figures_, "wall_time": time.perf_counter() - start}
    progress.stage("validity")

    def validity(X):
        here = min(len(X), executor.workers) <= 1
        ok = problem.validity(X) if here else map_blocks(executor, validity_task, X)
        progress.tested(len(X))
        return ok

    try:
        curve = robustness_on(executor, x, validity, samples, seed, physics, progress)
    finally:
        executor.close()
    wall = time.perf_counter() - start
    plot_curves({name: curve}, plot, title=f"{scenario.name}: local robustness of {name}")
    return {**common, **figures(curve, physics), "validity_tests": curve.validity_tests,
            "samples_per_radius": samples, "eta": curve.eta, "wall_time": wall}
