"""The user's own layouts as starts of ``rgmcad optimize --start LAYOUT`` and the choice of
the layout a run hands out.

A start is what ``simulate --layout`` accepts (a named layout of the scenario or a layout
file); :func:`resolve_starts` reads and checks them all before any simulation. The starts
join the run's identity and its default directory's name (:func:`starts_tag`).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rgmcad.errors import RgmcadError, UsageError
from rgmcad.learning.close_in import first_sound
from rgmcad.runs.robustness import two_rates
from rgmcad.sim.run import Outcome

__all__ = ["resolve_starts", "check_starts_valid", "starts_tag", "safe_name", "choose_layout"]

OPTION = "--start"
_CENTERING_STREAM, _SECOND_LOOK_STREAM = 2, 3


def resolve_starts(scenario, layouts: Sequence[str],
                   option: str = OPTION) -> dict[str, np.ndarray]:
    """Name -> normalised vector (d,) in [0, 1]^d of each start layout, in order; a layout
    file is named by its stem. Raises :class:`~rgmcad.errors.UsageError` naming ``option``
    for an unknown or unreadable layout or one outside the free ranges."""
    from rgmcad.scene.design_space import bounds, vector_from_values
    from rgmcad.scene.layout_files import resolve_layout

    starts: dict[str, np.ndarray] = {}
    low, high = bounds(scenario)
    for given in layouts:
        try:
            _, values = resolve_layout(scenario, given, None)
        except RgmcadError as exc:
            raise UsageError(option, given, f"expected a layout of {scenario.name} or a layout "
                             f"file ({exc})") from None
        x = vector_from_values(scenario, values)
        outside = [f"{f.name} = {v:g} not in [{lo:g}, {hi:g}]" for f, v, lo, hi, u in
                   zip(scenario.free, values, low, high, x, strict=True)
                   if not -1e-9 <= u <= 1 + 1e-9]  # a bound's rounding is inside
        if outside:
            raise UsageError(option, given, "outside the free ranges of the scenario: "
                             + ", ".join(outside))
        name = given if given in scenario.layouts else Path(given).stem
        while name in starts:  # two files of the same stem
            name += "'"
        starts[name] = np.clip(x, 0.0, 1.0)
    return starts


def check_starts_valid(problem, starts: dict[str, np.ndarray], option: str = OPTION) -> None:
    """Refuse a start whose bodies overlap (the simulator would never run it)."""
    if not starts:
        return
    ok = np.asarray(problem.validity(np.vstack(list(starts.values()))), dtype=bool)
    bad = [name for name, valid in zip(starts, ok, strict=True) if not valid]
    if bad:
        raise UsageError(option, bad[0], "its parts overlap (an invalid layout; `rgmcad "
                         "simulate --layout` shows where): expected a valid layout")


def starts_tag(starts: Sequence[str]) -> str:
    """``-from-NAME[+NAME...]`` for a default run directory (empty without starts)."""
    if not starts:
        return ""
    return "-from-" + "+".join(safe_name(name) for name in starts)


def safe_name(name: str) -> str:
    """``name`` with every character but letters, digits, ``_``, ``.``, ``-`` made ``_``: a
    layout's name as part of a folder's name."""
    return re.sub(r"[^A-Za-z0-9_.-]", "_", name)


def choose_layout(recorded, result, starts: dict[str, np.ndarray] | None = None,
                  seed: int = 0, on_stage=None) -> dict:
    """The layout to hand out, by simulation (:func:`rgmcad.learning.verify_layout`), with
    the words the summary gives for where it came from; then the second look
    (:func:`rgmcad.learning.second_look`) when the settings ask for it. ``seed`` seeds the
    centring and the second look's fit (streams of their own: the learning's draws do not
    depend on them). ``on_stage(name)`` is told when the second look and the close-in
    screen begin."""
    from rgmcad.learning import second_look, verify_layout

    seen_X, seen = [result.X], list(result.labels)

    def simulate(P):  # every simulation of the choice, for the second look's model
        labels = recorded.simulate(P)
        seen_X.append(np.atleast_2d(P))
        seen.extend(labels)
        return labels

    v = verify_layout(result.model, result.x, result.X, result.labels, simulate,
                      recorded.validity, result.settings, starts=starts,
                      rng=np.random.default_rng([seed, _CENTERING_STREAM]),
                      exploration_successes=result.n_exploration_successes)
    c, final, looks, kept = v.chosen, v.chosen, [], []
    s = result.settings
    if v.verified and s.second_look and s.verify_samples:
        if on_stage is not None:
            on_stage("second look")
        for k in range(s.second_look_rounds):  # another look only after one that moved
            stream = [seed, _SECOND_LOOK_STREAM, k] if k else [seed, _SECOND_LOOK_STREAM]
            looks.append(second_look(recorded, s, np.vstack(seen_X), seen, final, simulate,
                                     np.random.default_rng(stream), look=k))
            kept.append(looks[-1].chosen is not final)
            if not kept[-1]:
                break
            final = looks[-1].chosen
    optimum = Outcome(v.optimum.outcome)
    if not v.verified:
        source = (f"optimum, unverified: its simulation gave {optimum} and no "
                  "simulated layout succeeded")
    elif c.source == "optimum":
        source = "optimum"
    elif optimum is not Outcome.SUCCESS:
        source = f"{c.source} (the optimum's simulation gave {optimum})"
    else:
        source = f"{c.source} (more robust than the optimum under errors)"
    centering = None
    if v.centering is not None:
        pair = v.centering_check
        centering = {"radii": [float(r) for r in v.centering.radii],
                     "hit_rates": [float(p) for p in v.centering.hit_rates],
                     "simulations": v.centering.n_simulations, "kept": c.centered,
                     "check": None if pair is None else {
                         "errors": result.settings.centering_check_samples,
                         "before": pair[0].success_rate, "centre": pair[1].success_rate,
                         "valid_copies": [pair[0].n_valid, pair[1].n_valid],
                         "vector": [float(u) for u in pair[1].x]}}
    if c.centered:
        before, after = two_rates(v.centering_check[0].success_rate, c.success_rate)
        source += f", centred by simulation (success under errors {before} -> {after})"
    for k, look in enumerate(looks):
        if kept[k]:
            before, after = two_rates(look.check[0].success_rate, look.chosen.success_rate)
            source += (f", then refined again on the run's simulations (success under new "
                       f"errors {before} -> {after})" if k == 0 else f", and again ({before} "
                       f"-> {after})")
    n_look, screen, n_screen = sum(look.n_simulations for look in looks), None, 0
    if s.close_in_copies and v.verified:
        # the layout handed out must succeed where it is placed almost exactly; else the one
        # it came from, then the race's runners-up, best rated first, whichever does first
        if on_stage is not None:
            on_stage("close-in screen")
        order = list({id(t): t for t in (final, c, *v.runners_up)}.values())
        sound, passed_over, n_screen = first_sound(order, recorded.simulate, recorded.validity,
                                                   s.close_in_copies)
        screen = {"copies": s.close_in_copies, "simulations": n_screen,
                  "passed_over": list(passed_over), "kept": sound.source}
        if sound is not final:
            final = sound
            source = (f"{sound.source}, kept by the knife-edge screen: {' and '.join(passed_over)}"
                      f" failed at a layout within 1/300 of itself")
    # what the final choice by hand picks from: the layout kept, then the race's others that
    # succeeded where placed and were not passed over by the knife-edge screen
    passed = set(screen["passed_over"]) if screen else set()
    finalists = [final] + ([t for t in {id(t): t for t in (c, *v.runners_up)}.values()
                            if t is not final and t.outcome == "success"
                            and t.source not in passed] if v.verified else [])
    return {"x": final.x, "source": source, "verified": v.verified,
            "finalists": [{"source": t.source, "x": t.x} for t in finalists],
            "is_optimum": final.source == "optimum" and not final.centered,
            "optimum_outcome": optimum.value,
            "n_simulations": v.n_simulations + n_look + n_screen,
            "by_stage": {"verification": v.n_simulations - v.n_centering_simulations,
                         **({"centering": v.n_centering_simulations}
                            if v.n_centering_simulations else {}),
                         **({"second look": n_look} if n_look else {}),
                         **({"close-in screen": n_screen} if n_screen else {})},
            "centering": centering,
            "second_look": _look_summary(looks[0], kept[0]) if looks else None,
            **({"more_looks": [_look_summary(lk, kp) for lk, kp in zip(looks[1:], kept[1:],
                                                                      strict=True)]}
               if len(looks) > 1 else {}),
            **({"close_in": screen} if screen else {}),
            "race_stages": list(v.race_stages),
            "candidates": [{"source": t.source, "vector": [float(u) for u in t.x],
                            "success_rate": t.success_rate, "valid_copies": t.n_valid,
                            **({"moved_from": t.moved_from} if t.moved_from else {})}
                           for t in v.candidates]}


def _look_summary(look, refined: bool) -> dict:
    """result.json's account of one look."""
    out = {"simulations": look.n_simulations, "kept": refined, "check": None}
    if look.check is not None:
        before, after = look.check
        out["check"] = {"before": before.success_rate, "refined": after.success_rate,
                        "valid_copies": [before.n_valid, after.n_valid],
                        "vector": [float(u) for u in after.x], "source": after.source}
    return out
