"""The workflow behind ``rgmcad optimize`` (``rgmcad evaluate``'s is
:mod:`rgmcad.runs.evaluation`).

:func:`optimize_scenario`: learn a scenario's success probability and refine the most robust
layout (paper sections 5-7) in a run directory that survives interruptions
(:mod:`rgmcad.runs.store`), let the simulator choose the layout to hand out
(:mod:`rgmcad.learning.verify`), and write the run's outputs: ``layout.json`` (placement
tolerances in real units), ``start.json``, ``result.json`` (written last: the run is
finished), ``report.md`` and its plots (:mod:`rgmcad.runs.report`).

It spreads simulations over a process pool (:mod:`rgmcad.runs.executor`) and reports
progress to a :class:`RunProgress`; it does not print.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rgmcad.errors import ScenarioError, UsageError
from rgmcad.parts.family import family_digest
from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.checks import (
    MAX_BATCH,
    MAX_SEED,
    check_range,
    check_workers,
)
from rgmcad.runs.executor import make_executor, scheduler_from_env
from rgmcad.runs.hand import (
    DEFAULT_HAND,
    HAND_SETTINGS,
    Builds,
    Hand,
    chosen_by_hand,
    hand_figures,
)
from rgmcad.runs.outputs import LAYOUT_FILE, START_FILE, at_layout, write_outputs
from rgmcad.runs.problem import ScenarioProblem, SimRecord, scenario_digest
from rgmcad.runs.starts import check_starts_valid, choose_layout, resolve_starts, starts_tag
from rgmcad.runs.store import SIMULATIONS, RecordedProblem, RunStore, run_identity
from rgmcad.runs.tolerance_check import (
    POINTS,
    check_tolerances,
    confirm_as_printed,
    flags_of,
    printed_step,
    success_of,
    values_success_on,
)
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsRanges, corner_worlds

__all__ = ["LAYOUT_FILE", "START_FILE", "RunProgress", "OptimizationRun", "default_run_dir",
           "optimize_scenario"]

class RunProgress:
    """Where a workflow stands, for a progress display; every method does nothing here."""

    def stage(self, name: str, total: int | None = None) -> None:
        """A stage begins (``"exploration"``, ``"active:<event>"``, ``"verification"``,
        ``"second look"``, ``"validity"``, ``"simulation"``...), of ``total`` items if known."""

    def simulated(self, record: SimRecord, replayed: bool = False) -> None:
        """One simulation finished (or was read back from the run directory)."""

    def tested(self, n: int) -> None:
        """``n`` more layouts were tested for validity."""

    def built(self, record: SimRecord) -> None:
        """One more build of a layout placed by hand was simulated (:mod:`rgmcad.runs.hand`:
        not a layout of the run, not counted among its simulations)."""

    def measured(self, figures: dict) -> None:
        """A figure is known before the command ends (``{"hand": HandRate JSON}``: the
        headline, before the curve and the weak links), for a person waiting on it."""


@dataclass(frozen=True)
class OptimizationRun:
    """What :func:`optimize_scenario` did: the run directory, its ``result.json``
    (``summary``), whether it held a finished run (``finished_before``: nothing was computed)
    and the seconds this call took (``wall_time``)."""

    run_dir: Path
    summary: dict
    finished_before: bool
    wall_time: float

    @property
    def verified(self) -> bool:
        return bool(self.summary["verified"])


def default_run_dir(scenario_name: str, budget: str, seed: int, batch: int | None = None,
                    full: bool = False, starts: Sequence[str] = (),
                    centering: str | None = None, changes: Mapping | None = None) -> Path:
    """``runs/SCENARIO-sSEED``, or ``runs/SCENARIO-BUDGET-sSEED`` for another budget, with
    ``-bN`` (``--batch``), ``-full``, ``-centring-always|off`` (``--centering``), ``-KEY=VALUE``
    (each setting changed, ``--set``, by name) and ``-from-NAME+...`` (the start layouts,
    ``--start``) before ``-sSEED``."""
    tag = "" if budget == "default" else f"-{budget}"
    tag += ("" if batch is None else f"-b{batch}") + ("-full" if full else "")
    tag += "" if centering in (None, "auto") else f"-centring-{centering}"
    tag += "".join(f"-{k}={_setting_text(v)}" for k, v in sorted((changes or {}).items()))
    tag += starts_tag(starts)
    return Path("runs") / f"{scenario_name}{tag}-s{seed}"


def _setting_text(value) -> str:
    if isinstance(value, tuple):
        return ",".join(_setting_text(v) for v in value)
    return str(value).lower() if isinstance(value, bool | None) else str(value)


def optimize_scenario(
    scenario_path: str | Path, *, seed: int = 0, budget: str = "default", settings=None,
    run_dir: str | Path | None = None, workers: int | None = None,
    build_dir: str | Path = DEFAULT_BUILD_DIR, progress: RunProgress | None = None,
    recorded: Callable[..., RecordedProblem] = RecordedProblem,
    parts_dir: str | Path | None = None, scheduler: str | None = None,
    batch: int | None = None, robustness_samples: int = 0,
    physics: PhysicsRanges | None = DEFAULT_PHYSICS, physics_noise: PhysicsRanges | None = None,
    physics_corners: PhysicsRanges | None = None, full: bool = False,
    starts: Sequence[str] = (), centering: str | None = None,
    changes: Mapping | None = None, tolerance_check: bool = True,
    hand: Hand | None = DEFAULT_HAND,
) -> OptimizationRun:
    """Optimise a scenario's layout in a run directory, or continue an interrupted run there.

    Parameters
    ----------
    scenario_path : the scenario file.
    seed : of every random choice, 0..2^32 - 1.
    budget : name of the settings (:func:`~rgmcad.learning.settings.budget`); part of the
        default run directory's name and of the summary.
    settings : LearningSettings, optional
        Instead of the budget's.
    run_dir : default :func:`default_run_dir`. A directory made for other settings is
        refused (:class:`~rgmcad.errors.RunDirectoryError`).
    workers : simulation processes, 1..:func:`~rgmcad.runs.executor.max_workers` (None: every
        CPU); results do not depend on it.
    recorded : ``recorded(problem, store, executor, on_simulation)``: the problem the learner
        sees (a subclass of :class:`~rgmcad.runs.store.RecordedProblem` that times its calls,
        say).
    parts_dir : a folder of the user's part families (``--parts``; None: the shipped ones).
        Their digests join the run's identity.
    scheduler : a Dask scheduler's address or ``local:N`` (:mod:`rgmcad.runs.dask_executor`;
        None: ``RGMCAD_SCHEDULER`` if set, else ``workers`` local processes); results do not
        depend on it.
    batch : the exploration's batch size (``LearningSettings.exploration_batch``, 1..10 000)
        instead of the settings'; part of the run's identity and default directory.
    robustness_samples : when > 0, the chosen layout's rho_g is estimated with that many
        layouts per radius (``rgmcad evaluate``'s protocol, seed ``seed``), under placement
        errors and, with ``physics``, under placement plus physical errors: the summary's
        ``robustness``. Not journaled: an interrupted run redoes it.
    physics_noise : every learning (and verification) simulation with its own physical
        draw of these ranges (noisy labels: the model learns the success probability under
        physical errors); part of the run's identity, ``-physics`` ends the default directory.
    physics_corners : every learning (and verification) simulation run twice, with every
        body at the low and at the high end of these ranges, and labelled a success (each
        event too) only where both succeed: the model learns where the chain runs on the
        slipperiest and the grippiest table. Twice the simulations; part of the run's
        identity, ``-corners`` ends the default directory.
    full : one success model for the whole graph (``factorized=False``; paper Fig. 16).
    centering : ``LearningSettings.centering`` instead of the settings' (``"auto"``,
        ``"always"`` or ``"off"``); part of the run's identity and default directory.
    changes : ``{field: value}`` of LearningSettings changed from the settings' (``--set``);
        part of the run's identity and default directory.
    starts : the user's layouts to start from (``--start``: names of the scenario's layouts
        or layout files, :mod:`rgmcad.runs.starts`), checked before any simulation;
        simulated first by the exploration and always candidates of the final choice. Part
        of the run's identity and default directory.
    tolerance_check : simulate each side of each printed tolerance and narrow those that fail
        (:mod:`rgmcad.runs.tolerance_check`; False: the model's, as the benchmark keeps them).
    hand : the chosen layout's success when a person places every part with these errors,
        under ``physics`` (:func:`~rgmcad.runs.hand.hand_figures`, as many builds as the
        budget's :data:`~rgmcad.runs.hand.HAND_SETTINGS`, seed ``seed``): the summary's
        ``hand``. None: not measured. Not journaled: an interrupted run redoes it.
    """
    start = time.perf_counter()
    from rgmcad.learning.settings import budget as budget_settings
    from rgmcad.scene.loader import load_scenario

    progress = progress or RunProgress()
    check_range(seed, 0, MAX_SEED, "seed", "a seed")
    check_workers(workers, "workers")
    scenario = load_scenario(scenario_path, parts_dir=parts_dir)
    settings = budget_settings(budget) if settings is None else settings
    settings = settings.replace(factorized=False) if full else settings
    settings = settings if centering is None else settings.replace(centering=centering)
    settings = settings.replace(**(changes or {}))
    given = run_dir is not None
    if batch is not None:
        check_range(batch, 1, MAX_BATCH, "batch", "a number of simulations per batch")
        settings = settings.replace(exploration_batch=int(batch))
    parts = None if parts_dir is None else {
        name: family_digest(family) for name, family in scenario.families.items()}
    start_vectors = resolve_starts(scenario, starts)
    identity = run_identity(scenario.name, scenario_digest(scenario_path), seed, settings, parts)
    if start_vectors:
        identity["starts"] = [[float(u) for u in x] for x in start_vectors.values()]
    if physics_noise is not None:  # noisy labels: another run
        identity["physics_noise"] = physics_noise.to_json()
    if physics_corners is not None:
        identity["physics_corners"] = physics_corners.to_json()
    tag = ("" if physics_noise is None else "-physics") + (
        "" if physics_corners is None else "-corners")
    run_dir = Path(run_dir) if run_dir else default_run_dir(
        scenario.name, budget, seed, batch, full, list(start_vectors), centering, changes)
    run_dir = run_dir.with_name(run_dir.name + tag) if tag and not given else run_dir
    problem = ScenarioProblem(scenario_path, build_dir, parts_dir) if start_vectors else None
    check_starts_valid(problem, start_vectors)  # before any simulation
    with (_no_folder_if_refused(run_dir),  # closes the store before removing the folder
          RunStore(run_dir, identity, dimension=len(scenario.free),
                   events=list(scenario.events)) as store):
        summary = store.read_result()  # None unless finished, with its model intact
        if summary is not None and _readable_json(run_dir / LAYOUT_FILE):
            _check_same_hand(summary, hand, physics, run_dir, scenario_path)
            return OptimizationRun(run_dir, _placed_in(summary, run_dir), True,
                                   time.perf_counter() - start)
        from rgmcad.learning import NoValidLayoutError, learn_and_optimize
        from rgmcad.learning.parallel import jobs_on

        problem = problem or ScenarioProblem(scenario_path, build_dir, parts_dir)
        executor = make_executor(workers, problem.context, scheduler=scheduler_from_env(scheduler),
                                 payload=problem.payload)
        try:
            learner_problem = recorded(problem, store, executor, progress.simulated)
            if physics_noise is not None:
                learner_problem.physics_noise = (physics_noise, seed)
            if physics_corners is not None:
                learner_problem.physics_worlds = corner_worlds(physics_corners)
            # The pool is idle while the models train: their grid searches, calibration folds
            # and mutual information estimates run there (never changing the result).
            with jobs_on(executor):
                try:
                    result = learn_and_optimize(
                        learner_problem, settings, seed,
                        # the learner's "done" is the run's middle: the choice follows
                        on_progress=lambda p: p.stage == "done" or progress.stage(p.stage),
                        starts=np.vstack(list(start_vectors.values())) if start_vectors else None)
                except NoValidLayoutError as exc:
                    raise ScenarioError(
                        scenario_path, "free", f"{exc} (parts overlap in every one): expected "
                        "free ranges where the parts can stand apart; `rgmcad simulate "
                        f"{scenario_path} --vector {','.join(['0.5'] * len(scenario.free))}` "
                        "shows which overlap in the middle of the ranges") from None
            progress.stage("verification")
            with jobs_on(executor):  # the second look fits the models again
                chosen = choose_layout(learner_problem, result, start_vectors, seed,
                                       on_stage=progress.stage)
            hand_settings = HAND_SETTINGS.get(budget, HAND_SETTINGS["default"])
            builds = Builds(executor, progress)
            if hand is not None and len(chosen["finalists"]) > 1:  # the maker's measure decides
                progress.stage("choice by hand", len(chosen["finalists"]) * hand_settings.maximum)
                chosen = chosen_by_hand(chosen, builds, hand, physics, seed, hand_settings)
            robustness = None
            if robustness_samples:
                from rgmcad.runs.robustness import figures, robustness_on

                progress.stage("robustness")
                curve = robustness_on(executor, np.asarray(chosen["x"], dtype=float),
                                      learner_problem.validity, robustness_samples, seed,
                                      physics, progress)
                robustness = {"samples_per_radius": robustness_samples,
                              **figures(curve, physics)}
            model_view = at_layout(result.model, result, chosen,
                                   np.asarray(chosen["x"], dtype=float), learner_problem.validity)
            checked = None
            if tolerance_check and chosen["verified"]:  # a failing layout's mean nothing
                # about: each side's places, its range's end, two hairs (halvings not counted)
                progress.stage("tolerance check",
                               int(np.count_nonzero(model_view[-1] > 0)) * (POINTS + 3))
                checked = check_tolerances(np.asarray(chosen["x"], dtype=float), model_view[-1],
                                           success_of(learner_problem), printed_step(scenario))
                checked = confirm_as_printed(checked, np.asarray(chosen["x"], dtype=float),
                                             scenario, values_success_on(executor))
            by_hand = None
            if hand is not None:
                by_hand = hand_figures(executor, problem, chosen["x"], hand, physics, seed,
                                       hand_settings, progress, builds=builds)
                by_hand = {**by_hand, "seed": seed}
                if checked is not None and hand_settings.bound_samples:
                    checked, by_hand = _tolerances_by_hand(
                        checked, chosen["x"], model_view[-1], result.settings, learner_problem,
                        executor, builds, hand, physics, seed, hand_settings, progress, by_hand)
        finally:
            executor.close()
        summary = write_outputs(scenario, store, learner_problem, result, chosen,
                                 time.perf_counter() - start, seed, budget, robustness,
                                 start_vectors, model_view, checked, by_hand)
    progress.stage("done")
    return OptimizationRun(run_dir, summary, False, time.perf_counter() - start)


@contextmanager
def _no_folder_if_refused(run_dir: Path):
    """A run refused before any simulation (a :class:`ScenarioError`) leaves no run
    directory behind, unless the directory was there before."""
    fresh = not run_dir.exists()
    try:
        yield
    except ScenarioError:
        journal = run_dir / SIMULATIONS
        if fresh and journal.is_file() and journal.stat().st_size == 0:
            shutil.rmtree(run_dir, ignore_errors=True)
        raise


def _tolerances_by_hand(checked, x, model_tol, settings, learner_problem, executor, builds,
                        hand, physics, seed, hand_settings, progress, by_hand):
    """Each printed side at its bound with every part placed by hand
    (:mod:`rgmcad.runs.hand_bounds`), those narrowed there confirmed again as printed; the
    sides that stop against a part are left alone. Returns (checked, by_hand with its
    ``tolerances``)."""
    from rgmcad.learning import overlap_ends
    from rgmcad.runs.hand_bounds import hand_at_bounds

    x = np.asarray(x, dtype=float)
    meet = flags_of(overlap_ends(x, model_tol, settings, learner_problem.problem.validity)) \
        & ~checked.narrowed
    scenario = learner_problem.problem.scenario
    progress.stage("tolerances by hand", int(np.count_nonzero(checked.tolerances > 0))
                   * hand_settings.bound_samples)
    bounds = hand_at_bounds(checked, x, scenario, builds, hand, physics, seed,
                            hand_settings.bound_samples, meet, hand_settings.precision)
    if bounds.narrowed.any():
        checked = confirm_as_printed(bounds.checked, x, scenario, values_success_on(executor))
    else:
        checked = bounds.checked
    return checked, {**by_hand, "tolerances": bounds.to_json(scenario),
                     "simulations": by_hand["simulations"] + bounds.simulations}


def _check_same_hand(summary: dict, hand: Hand | None, physics: PhysicsRanges | None,
                     run_dir: Path, scenario_path) -> None:
    """A finished run is shown as it is; asked for with another hand (or other physical
    errors under it), its figures would answer a question nobody asked: refused, with the
    command that measures its layout under the hand asked for."""
    if hand is None:
        return
    stored = (summary.get("hand") or {}).get("hand")
    physics_json = None if physics is None else physics.to_json()
    if stored is not None and stored["physics"] == physics_json and all(
            stored[k] == v for k, v in hand.to_json().items()):
        return
    if stored is None:
        key, was = "--hand", "no hand (--hand off)"
    elif stored["physics"] != physics_json:
        old = stored["physics"]
        key, was = "--physics", "physical errors " + (
            "off" if old is None else PhysicsRanges(**old).describe())
    else:
        key, was = "--hand", "a hand " + Hand(stored["position_mm"], stored["heading_deg"]
                                              ).describe()
    raise UsageError(key, "", f"{run_dir} finished for {was} and chose its layout for it; "
                     f"measure that layout under yours with `rgmcad evaluate {scenario_path} "
                     f"--layout {run_dir / LAYOUT_FILE} {key} ...`, or optimise for yours in "
                     "a new run (--run DIR)")


def _placed_in(summary: dict, run_dir: Path) -> dict:
    """A finished run's summary naming its files in ``run_dir`` (it may have been moved)."""
    start = {**summary.get("start", {}), "layout": str(run_dir / START_FILE)}
    return {**summary, "run": str(run_dir), "layout": str(run_dir / LAYOUT_FILE), "start": start}


def _readable_json(path: Path) -> bool:
    try:
        json.loads(path.read_text())
        return True
    except (OSError, ValueError):
        return False
