"""The workflow behind ``rgmcad evaluate``: a layout's local and global robustness by
simulation (:mod:`rgmcad.runs.robustness`) and its plot, the simulations spread over a process
pool (:mod:`rgmcad.runs.executor`), progress reported to a
:class:`~rgmcad.runs.workflow.RunProgress`; it does not print."""

from __future__ import annotations

import time
from pathlib import Path

from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.checks import MAX_SAMPLES, MAX_SEED, check_plot_file, check_range, check_workers
from rgmcad.runs.executor import make_executor, map_blocks, scheduler_from_env
from rgmcad.runs.problem import ScenarioProblem, validity_task
from rgmcad.runs.workflow import RunProgress
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsRanges

__all__ = ["evaluate_layout"]


def evaluate_layout(
    scenario_path: str | Path, layout: str, *, samples: int = 50, seed: int = 0,
    workers: int | None = None, build_dir: str | Path = DEFAULT_BUILD_DIR,
    plot: str | Path | None = None, progress: RunProgress | None = None,
    parts_dir: str | Path | None = None, scheduler: str | None = None,
    physics: PhysicsRanges | None = DEFAULT_PHYSICS,
) -> dict:
    """Local robustness of a layout at every radius and its global robustness rho_g
    (:func:`~rgmcad.runs.robustness.local_robustness`), and their plot; with ``physics``
    (default: :data:`~rgmcad.scene.perturbation.DEFAULT_PHYSICS`; None: placement only),
    also under placement plus physical errors, on the same layouts.

    Parameters
    ----------
    layout : a named layout of the scenario or a layout file.
    samples : valid layouts simulated per radius, 1..100 000.
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
    check_range(samples, 1, MAX_SAMPLES, "samples", "a number of layouts per radius")
    check_range(seed, 0, MAX_SEED, "seed", "a seed")
    check_workers(workers, "workers")
    scenario = load_scenario(scenario_path, parts_dir=parts_dir)
    name, values = resolve_layout(scenario, layout, None)
    x = vector_from_values(scenario, values)
    if plot is None:
        plot = (Path(layout).with_name(f"{Path(layout).stem}-robustness.png")
                if Path(layout).is_file() else Path(f"robustness-{scenario.name}-{name}.png"))
    check_plot_file(plot, "plot")  # before the simulations, not after
    start = time.perf_counter()
    problem = ScenarioProblem(scenario_path, build_dir, parts_dir)
    executor = make_executor(workers, problem.context, scheduler=scheduler_from_env(scheduler),
                             payload=problem.payload)
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
    return {"scenario": scenario.name, "layout": name, "vector": [float(v) for v in x],
            **figures(curve, physics), "validity_tests": curve.validity_tests,
            "samples_per_radius": samples, "eta": curve.eta, "seed": seed,
            "wall_time": wall, "plot": str(plot)}

