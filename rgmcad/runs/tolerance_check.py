"""Placement tolerances a maker can trust: the model's, each side then simulated.

The learnt model says how far each free parameter may move, alone, before the predicted
success drops (:func:`~rgmcad.learning.placement_tolerance`). A model can be confidently wrong
(a user's ``track1.x`` was printed +51 mm and failed at +45 mm), so every side is simulated
before it is printed: the layout with that one parameter moved to ``POINTS`` evenly spaced
places up to the bound, each a whole number of 0.1 mm or 0.1 degree (the printed resolution).
A side where one of them fails is narrowed to the last place that succeeded, refined by
``BISECTIONS`` halvings towards the first that failed; the side printed then succeeds at its
bound, the very number printed, and at every place checked before it.

The simulations are the run's (journaled, so an interrupted run replays them), under the
run's physics; a side that reaches the end of its range or stops where parts meet is checked
like any other.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

__all__ = ["POINTS", "BISECTIONS", "JITTER", "CONFIRM_STEPS", "CheckedTolerances",
           "check_tolerances", "confirm_as_printed", "values_success_on", "printed_offsets", "printed_step",
           "sides_of", "flags_of", "success_of", "pushed_against", "narrowed_note",
           "tolerance_header"]

POINTS = 4
"""Places simulated along each side, the bound the last: a quarter, half, three quarters."""

JITTER = 0.1
"""Each bound is simulated again this fraction of a printed step either side (0.01 mm)."""

CONFIRM_STEPS = 5
"""Steps in, one printed step each, for a bound that fails a hair from itself."""

BISECTIONS = 4
"""Halvings between the last place that succeeded and the first that failed: a narrowed side
is within 1/64 of the model's tolerance (or 0.1 mm) of where the layout starts failing."""


@dataclass(frozen=True)
class CheckedTolerances:
    """Result of :func:`check_tolerances`.

    Attributes
    ----------
    tolerances : (d, 2) float
        ``[[down, up], ...]`` normalised: the model's where every place simulated succeeded,
        else the narrowed side.
    narrowed : (d, 2) bool
        Sides where a simulated place failed.
    simulations : int
        Layouts simulated (places and halvings).
    """

    tolerances: np.ndarray
    narrowed: np.ndarray
    simulations: int


def check_tolerances(x: np.ndarray, tolerances: np.ndarray,
                     succeeds: Callable[[np.ndarray], np.ndarray], step: np.ndarray,
                     points: int = POINTS, bisections: int = BISECTIONS) -> CheckedTolerances:
    """Simulate each side of ``tolerances`` around ``x`` and narrow the sides that fail.

    Every place simulated is a whole number of ``step`` from ``x``, the model's tolerance
    rounded down to one: the number printed (to 0.1 mm or 0.1 degree) is a place simulated,
    not a neighbour of one (between neighbours 0.1 mm apart a chain can fail). A side that
    reaches the end of its range is simulated at the end too and, if all its places
    succeed, keeps the range's end exactly (printed "end of range").

    Parameters
    ----------
    x : (d,) float
        The layout, normalised.
    tolerances : (d, 2) float
        The model's ``[[down, up], ...]``, normalised, >= 0.
    succeeds : ``(n, d) -> (n,) bool``
        Whether each layout succeeds in simulation (an invalid layout does not); called once
        for all the places, then once per halving.
    step : (d,) float
        The resolution of each parameter as printed, normalised (0.1 mm or 0.1 degree over
        the parameter's range).
    """
    x = np.asarray(x, dtype=float).reshape(-1)
    step = np.broadcast_to(np.asarray(step, dtype=float), x.shape)
    model = np.asarray(tolerances, dtype=float).reshape(len(x), 2)
    room = np.column_stack([x, 1.0 - x])
    whole = np.floor(model / step[:, None] + 1e-6).astype(int)  # steps of each side
    to_end = model >= room - 1e-9
    sides = [(j, k) for j in range(len(x)) for k in range(2) if model[j, k] > 0]

    def moved(side, offset):
        j, k = side
        p = x.copy()
        p[j] = np.clip(x[j] + (offset if k else -offset), 0.0, 1.0)
        return p

    places = {}
    for s in sides:  # offsets, normalised: whole steps, and the range's end where reached
        grid = {max(1, int(whole[s] * f)) * step[s[0]]
                for f in np.arange(1, points + 1) / points} if whole[s] else set()
        places[s] = sorted(grid | ({float(room[s])} if to_end[s] else set()))
    batch = [(s, t) for s in sides for t in places[s]]
    ok = (np.asarray(succeeds(np.array([moved(s, t) for s, t in batch])), dtype=bool)
          if batch else np.zeros(0, bool))
    simulations = len(batch)
    first_failure: dict = {}
    for (s, t), o in zip(batch, ok, strict=True):
        if not o and s not in first_failure:
            first_failure[s] = t
    # halvings in whole steps between the last place that succeeded and the first that failed
    good = {s: int(round(max([0.0] + [t for t in places[s] if t < bad]) / step[s[0]]))
            for s, bad in first_failure.items()}
    bad = {s: int(np.ceil(t / step[s[0]] - 1e-6)) for s, t in first_failure.items()}
    for _ in range(bisections):
        keys = [s for s in bad if bad[s] - good[s] > 1]
        if not keys:
            break
        mids = [(good[s] + bad[s]) // 2 for s in keys]
        ok = np.asarray(succeeds(np.array([moved(s, m * step[s[0]]) for s, m in zip(
            keys, mids, strict=True)])), bool)
        simulations += len(keys)
        for s, m, o in zip(keys, mids, ok, strict=True):
            (good if o else bad)[s] = m
    out = np.where(to_end, room, whole * step[:, None])
    narrowed = np.zeros(out.shape, dtype=bool)
    for s in bad:
        out[s], narrowed[s] = good[s] * step[s[0]], True
    # A bound a hair from a failure is no bound: on simple, moving track.z to a bound the
    # check had simulated, by way of the printed number (1.4e-17 m away), failed. Each bound
    # is simulated again JITTER of a step either side; a side where one fails steps in by
    # one printed step (the new bound simulated too), at most CONFIRM_STEPS times, then to 0.
    pending = {s: [t for t in (out[s] - JITTER * step[s[0]], out[s] + JITTER * step[s[0]])
                   if 0.0 < t <= room[s] + 1e-12] for s in sides if out[s] > 0}
    for _ in range(CONFIRM_STEPS + 1):
        batch = [(s, t) for s, ts in pending.items() for t in ts]
        if not batch:
            break
        ok = np.asarray(succeeds(np.array([moved(s, t) for s, t in batch])), dtype=bool)
        simulations += len(batch)
        failed = {s for (s, _), o in zip(batch, ok, strict=True) if not o}
        pending = {}
        for s in failed:
            out[s] = max(np.ceil(out[s] / step[s[0]] - 1e-6) - 1, 0) * step[s[0]]
            narrowed[s] = True
            if out[s] > 0:
                t = out[s]
                pending[s] = [t - JITTER * step[s[0]], t, t + JITTER * step[s[0]]]
    for s in pending:  # still failing after CONFIRM_STEPS steps in: no room on that side
        out[s] = 0.0
    return CheckedTolerances(out, narrowed, simulations)


def confirm_as_printed(checked: CheckedTolerances, x: np.ndarray, scenario,
                       simulate_values: Callable[[np.ndarray], np.ndarray],
                       steps: int = CONFIRM_STEPS) -> CheckedTolerances:
    """Each side of ``checked`` simulated once more as a maker moves it: the layout's real
    values with one parameter moved by the number printed (rounded down to 0.1 mm or 0.1
    degree, :func:`~rgmcad.runs.report.tolerance_text`), set as a real value: a run's
    simulations go through the normalised vector, and on a narrowed side a layout 1e-17 m
    away can fail. A side that fails steps in by one printed step, at most ``steps`` times,
    then to 0; every side printed is then a real layout that succeeded.
    ``simulate_values(V)``: (n, d) real values -> (n,) bool success."""
    from rgmcad.scene.design_space import bounds

    low, high = bounds(scenario)
    width = high - low
    values = low + np.asarray(x, float) * width  # as the run's summary states them
    unit = np.array([1.0 if f.unit == "deg" else 1000.0 for f in scenario.free])
    out, narrowed = checked.tolerances.copy(), np.zeros_like(checked.narrowed)
    printed = printed_offsets(out, scenario)
    simulations = checked.simulations
    for _ in range(steps + 1):
        sides = [s for s, p in printed.items() if p > 0]
        if not sides:
            break
        V = np.repeat(values[None], len(sides), axis=0)
        for row, (j, k) in enumerate(sides):
            V[row, j] += printed[j, k] if k else -printed[j, k]
        ok = np.asarray(simulate_values(V), dtype=bool)
        simulations += len(sides)
        for (j, k), o in zip(sides, ok, strict=True):
            if o:  # a side that held as first printed keeps its figure (a range's end)
                p = printed.pop((j, k))
                out[j, k] = p / width[j] if narrowed[j, k] else out[j, k]
            else:
                narrowed[j, k] = True
                printed[j, k] = max(round(printed[j, k] * unit[j] * 10) - 1, 0) / 10 / unit[j]
    for j, k in printed:  # no printed place left that works (or none to print)
        out[j, k] = 0.0
    return CheckedTolerances(out, narrowed | checked.narrowed, simulations)


def printed_offsets(tolerances: np.ndarray, scenario) -> dict[tuple[int, int], float]:
    """``{(j, k): offset}``: each side of (d, 2) normalised ``tolerances`` above 0 as printed
    (:func:`~rgmcad.runs.report.tolerance_text`: rounded down to 0.1 mm or 0.1 degree), in
    the parameter's real unit (metres or degrees), 0 where that rounds to nothing."""
    from rgmcad.runs.report import tolerance_text
    from rgmcad.scene.design_space import bounds

    low, high = bounds(scenario)
    unit = np.array([1.0 if f.unit == "deg" else 1000.0 for f in scenario.free])
    return {(j, k): float(tolerance_text(tolerances[j, k] * (high[j] - low[j]) * unit[j]))
            / unit[j] for j in range(len(unit)) for k in range(2) if tolerances[j, k] > 0}


def printed_step(scenario) -> np.ndarray:
    """(d,) 0.1 mm or 0.1 degree, the resolution tolerances are printed at, normalised."""
    from rgmcad.scene.design_space import bounds

    low, high = bounds(scenario)
    return np.array([0.1 if f.unit == "deg" else 1e-4 for f in scenario.free]) / (high - low)


def sides_of(flags: np.ndarray, scenario) -> dict[str, str]:
    """``{parameter: "low" | "high" | "both"}`` of the flagged sides of (d, 2) bool."""
    return {f.name: "both" if lo and hi else "low" if lo else "high"
            for f, (lo, hi) in zip(scenario.free, flags, strict=True) if lo or hi}


def pushed_against(context, x: np.ndarray, tolerances: np.ndarray, flags: np.ndarray,
                   past: float) -> dict[str, dict[str, str]]:
    """``{parameter: {"low" | "high": object}}``: for each flagged side (where moving the
    parameter ``past`` beyond its tolerance makes parts overlap), the part it then runs into
    (the deepest overlap with a part the parameter does not move). ``context``: the run's
    :class:`~rgmcad.runs.problem.ScenarioContext`."""
    from rgmcad.scene.bodies import make_scene
    from rgmcad.sim.validity import check_validity

    scenario = context.scenario
    out: dict[str, dict[str, str]] = {}
    for j, f in enumerate(scenario.free):
        moved = {f.object} | _descendants(scenario, f.object)
        for k, side in enumerate(("low", "high")):
            if not flags[j, k]:
                continue
            p = np.array(x, dtype=float)
            p[j] = np.clip(p[j] + (-1.0, 1.0)[k] * (tolerances[j, k] + past), 0.0, 1.0)
            scene = make_scene(scenario, context.values(p), context.parts)
            hits = []
            for overlap in check_validity(scene, cache=context.cache).overlaps:
                owners = [scene.bodies[b].object if b in scene.bodies else b
                          for b in (overlap.first, overlap.second)]
                if sum(o in moved for o in owners) == 1:
                    hits.append((overlap.depth, next(o for o in owners if o not in moved)))
            if hits:
                out.setdefault(f.name, {})[side] = max(hits)[1]
    return out


def _descendants(scenario, name: str) -> set[str]:
    children = {o.name for o in scenario.objects.values() if o.parent == name}
    return children.union(*(_descendants(scenario, c) for c in children))


def flags_of(sides: list[str | None]) -> np.ndarray:
    """(d, 2) bool of per-parameter sides ``"low"``, ``"high"``, ``"both"`` or None."""
    return np.array([[s in ("low", "both"), s in ("high", "both")] for s in sides], bool)


def values_success_on(executor):
    """``(n, d) real values -> (n,) bool``: whether each layout succeeds, simulated on
    ``executor`` (whose context is the scenario's); not journaled."""
    from rgmcad.runs.problem import simulate_values_task
    from rgmcad.sim.run import Outcome

    def succeeds(V):
        return np.array([r.outcome is Outcome.SUCCESS
                         for r in executor.map_context(simulate_values_task, list(V))])
    return succeeds


def success_of(recorded):
    """``(n, d) -> (n,) bool``: whether each layout succeeds, simulated (and journaled) by a
    :class:`~rgmcad.runs.store.RecordedProblem`."""
    from rgmcad.sim.run import Outcome

    def succeeds(P):
        return np.array([r.outcome is Outcome.SUCCESS for r in recorded.simulate_records(P)])
    return succeeds


def narrowed_note(s: dict) -> str:
    """What NARROWED means, with the model's figures of the sides it marks."""
    check = s.get("tolerance_check") or {}
    said = []
    for name, side in check.get("narrowed", {}).items():
        k, unit = (1.0, "deg") if name.split(".")[-1] in ("heading", "pitch", "roll") else (
            1000.0, "mm")
        down, up = check["model_tolerances"][name]
        said += [f"{name} {sign}{t * k:.1f} {unit}" for sign, t, here in (
            ("-", down, "low"), ("+", up, "high")) if side in (here, "both")]
    by_hand = ((s.get("hand") or {}).get("tolerances") or {}).get("narrowed")
    return ("a tolerance marked 'narrowed by simulation' is where the model was too generous "
            f"(it said {', '.join(said)}): the layout failed in simulation inside that bound"
            + (", or worked less often there when built by hand" if by_hand else "")
            + ", so the side stops where it still succeeded.")


def tolerance_header(s: dict) -> str:
    """How the tolerances were found: the model's alone, or checked by simulation."""
    check = s.get("tolerance_check")
    if not check:
        return ("placement tolerances (down / up), as the model predicts them (one parameter "
                "moved alone; `rgmcad simulate ... --value NAME=V` tries one)")
    text = (f"placement tolerances (down / up), one parameter moved alone: the model's, each "
            f"side then simulated at {check['points_per_side']} places up to its bound (its "
            f"bound included; {check['simulations']} simulations), and narrowed where one failed")
    by_hand = (s.get("hand") or {}).get("tolerances")
    if by_hand:
        text += (f"; then at its bound with every part placed by hand ({by_hand['samples']} "
                 f"builds, the layout's, {2 * by_hand['samples']} where that was not clear), "
                 f"and narrowed where it worked in more than {by_hand['precision']:.0%} of "
                 "them fewer than the layout")
    return text
