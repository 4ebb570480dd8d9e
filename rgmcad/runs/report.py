"""What a finished optimisation run shows: ``report.md`` and its plots.

The report is markdown written from the run's summary (``result.json``); the plots are
matplotlib figures (Agg), in the units the user works in (mm, degrees): the learnt success
model through the layout, the predicted success under placement errors, and the run's
progress. :mod:`rgmcad.runs.workflow` writes them into the run directory; the HTML report
(:mod:`rgmcad.viewer.report`) shows the same figures.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rgmcad.runs.hand_text import hand_headline, hand_markdown
from rgmcad.runs.robustness import close_in_warning, failures_line, save_figure, two_rates
from rgmcad.runs.tolerance_check import narrowed_note, tolerance_header
from rgmcad.scene.perturbation import PhysicsRanges

__all__ = ["REPORT_FILE", "SLICE_PLOT", "PROGRESS_PLOT", "ROBUSTNESS_PLOT", "HAND_PLOT", "ERROR_GRID",
           "RANGE_END", "RANGE_END_NOTE", "PARTS_MEET", "tolerance_text", "placement_lines",
           "tolerance_notes",
           "tolerance_paragraphs", "count_line", "range_end_marks", "report_markdown",
           "plot_slice", "plot_progress", "plot_robustness", "predicted_robustness", "user_scale",
           "side_texts"]

REPORT_FILE = "report.md"
SLICE_PLOT = "probability_slice.png"
PROGRESS_PLOT = "exploration.png"
ROBUSTNESS_PLOT = "robustness.png"
HAND_PLOT = "hand.png"
ERROR_GRID = np.linspace(0.0, 10.0, 21)
"""Standard deviations of the placement errors of :func:`predicted_robustness`: mm for
positions, degrees for angles."""


def tolerance_text(value: float) -> str:
    """A tolerance in mm or degrees as printed: rounded *down* to 0.1, so that the number a
    maker reads is inside what was checked (5.98 reads 5.9, never 6.0)."""
    return f"{math.floor(value * 10 + 1e-6) / 10:.1f}"


def user_scale(parameter) -> tuple[float, str]:
    """(factor from the parameter's real unit to the user's, the user's unit): metres to
    millimetres, degrees stay degrees."""
    return (1.0, "deg") if parameter.unit == "deg" else (1000.0, "mm")


RANGE_END = " (end of range)"
RANGE_END_NOTE = ("a tolerance marked 'end of range' stops where the parameter's range ends, "
                  "not where the layout fails: nothing beyond a range is simulated. If the "
                  "parts allow, widen that range in the scenario and run again: the layout "
                  "may then move away from the end.")


PARTS_MEET = " (parts meet)"
PARTS_MEET_NOTE = ("a tolerance marked 'parts meet' stops where moving that parameter further "
                   "would make two parts overlap: the layout cannot be built past it.")


PUSH_NOTE = ("'push against the X': slide the part along that parameter until it touches X; "
             "the layout was simulated there and works, so no number is needed.")

NARROWED = " (narrowed by simulation)"


def range_end_marks(s: dict, name: str) -> tuple[str, str]:
    """The marks of a parameter's tolerance down and up in a run's summary: RANGE_END on a
    side whose tolerance reaches the end of the range (``range_ends``), PARTS_MEET on one
    that stops where parts would overlap (``overlap_ends``), NARROWED on one the simulations
    of the tolerance check narrowed, else ""."""
    marks = []
    narrowed = (s.get("tolerance_check") or {}).get("narrowed", {})
    for side in ("low", "high"):
        # all absent from runs made before them
        ends = {key: s.get(key, {}).get(name) in (side, "both")
                for key in ("range_ends", "overlap_ends")}
        marks.append(RANGE_END if ends["range_ends"] else
                     PARTS_MEET if ends["overlap_ends"] else
                     NARROWED if narrowed.get(name) in (side, "both") else "")
    return marks[0], marks[1]


def side_texts(s: dict, name: str, k: float) -> tuple[str, str]:
    """A parameter's tolerance down and up as printed (``k``: to mm or degrees): "-2.3",
    "+4.0 (end of range)", or, where the part stops against another and was simulated
    there, "push against the floor" (no number: pushing a part against its neighbour is
    the easiest placement a hand makes)."""
    marks, push = range_end_marks(s, name), (s.get("push_against") or {}).get(name, {})
    return tuple(f"push against the {push[side]}" if side in push else
                 f"{sign}{tolerance_text(value * k)}{mark}"
                 for side, sign, value, mark in zip(("low", "high"), "-+", s["tolerances"][name],
                                                    marks, strict=True))


ROUGH_MODEL = 0.5
"""A layout that succeeded in simulation but that the model rates below this: the model is
rough there, and so are the tolerances it gives."""


def tolerance_paragraphs(s: dict) -> list[str]:
    """:func:`tolerance_notes` as sentences of their own (report.md, report.html)."""
    return [note[0].upper() + note[1:] for note in tolerance_notes(s)]


def tolerance_notes(s: dict) -> list[str]:
    """The notes under a run's tolerances: what the marks of :func:`range_end_marks` mean,
    and a caution when the model itself is too rough to give them."""
    push = s.get("push_against") or {}
    unpushed = any(side not in push.get(name, {}) for name, where in
                   (s.get("overlap_ends") or {}).items()
                   for side in (("low", "high") if where == "both" else (where,)))
    notes = ([RANGE_END_NOTE] if s.get("range_ends") else []) + (
        [PARTS_MEET_NOTE] if unpushed else []) + ([PUSH_NOTE] if push else []) + (
        [narrowed_note(s)] if (s.get("tolerance_check") or {}).get("narrowed") else [])
    if s.get("verified") and s["probability"] < ROUGH_MODEL:
        notes.append(
            f"the model rates this layout's success at {s['probability']:.2f}, though it "
            "succeeded when simulated: the model is rough here, and so are these tolerances "
            "(each side was simulated at its bound, but between the places checked only the "
            "model speaks); `rgmcad evaluate` measures the layout by simulation"
            + (", and the default budget learns a finer model" if s.get("budget") == "small"
               else "") + ".")
    return notes


def placement_lines(s: dict) -> list[str]:
    """A run's placement tolerances as ``rgmcad optimize`` prints them (mm and degrees)."""
    lines = [tolerance_header(s) + ":"]
    for name in s["tolerances"]:
        angle = name.split(".")[-1] in ("heading", "pitch", "roll")
        k, unit = (1.0, "deg") if angle else (1000.0, "mm")
        lines.append(f"  {name:24s} {s['values'][name] * k:8.1f} {unit:3s}  "
                     + " / ".join(side_texts(s, name, k)))
    lines += [f"note: {note}" for note in tolerance_notes(s)]
    return lines


def report_markdown(scenario, s: dict, low, high, making=()) -> str:
    """``report.md`` of a run from its summary (``result.json``); ``low``, ``high`` (d,): the
    parameters' ranges, real units; ``making``: lines (the first blank) put before the plots."""
    lines = [f"# {scenario.name}: optimised layout", "",
             f"- run: `{s['run']}` (seed {s['seed']}, budget {s['budget']})",
             f"- layout file: `{s['layout']}` (`--layout` of every command)",
             *([f"- built by hand: **{hand_headline(s['hand'])}**"] if s.get("hand") else []),
             f"- predicted success probability: **{s['probability']:.3f}**; weakest link: "
             f"`{s['weakest_event']}`",
             f"- chosen layout: {s['source']}; verified by simulation: "
             f"{'yes' if s['verified'] else 'NO'}",
             f"- simulations: {s['simulations']} ({s['successes']} successes; by stage: "
             + ", ".join(f"{k} {v}" for k, v in s["simulations_by_stage"].items()) + ")"
             + ("" if s.get("worlds", 1) == 1 else f"; each layout in {s['worlds']} physical "
                "worlds (`--physics-corners`), a success only where all succeeded"),
             *_exploration_lines(s.get("exploration")),
             f"- wall time: {s['wall_time']:.0f} s (simulation {s['simulation_seconds']:.0f} "
             "s of CPU)",
             f"- refinement: objective {s['optimization']['objective_start']:.3f} -> "
             f"{s['optimization']['objective']:.3f} ({s['optimization']['evaluations']} "
             f"evaluations, {s['optimization']['status']})",
             *_robustness_lines(s.get("robustness")), "",
             "## Per-event probability at the layout", "",
             "| event | P(success given parents) | model | parameters |", "|---|---|---|---|"]
    for e, p in s["event_probabilities"].items():
        f = s["factors"].get(e, {})
        mark = " (weakest)" if e == s["weakest_event"] else ""
        lines.append(f"| {e}{mark} | {p:.3f} | {f.get('model', '')} | "
                     f"{', '.join(f.get('dims', [])) or '-'} |")
    lines += hand_markdown(s.get("hand"), HAND_PLOT)
    lines += ["", "## Placement", "",
              "How far each parameter may move, alone, before the predicted success drops "
              "below 90 % of its value here (the parameter's whole range is shown for scale)"
              + (f"; each side then simulated at {check['points_per_side']} places up to its "
                 "bound, and narrowed where one failed." if (check := s.get("tolerance_check"))
                 else ": the model's figures, not simulated (the layout did not succeed)."),
              "", "| parameter | value | may move down | may move up | range |",
              "|---|---|---|---|---|"]
    for j, f in enumerate(scenario.free):
        k, unit = user_scale(f)
        down, up = (text.lstrip("+-") for text in side_texts(s, f.name, k))
        lines.append(f"| {f.name} | {s['values'][f.name] * k:.1f} {unit} | {down} | {up} | "
                     f"[{low[j] * k:.1f}, {high[j] * k:.1f}] |")
    for paragraph in tolerance_paragraphs(s):
        lines += ["", paragraph]
    if s.get("verification"):
        lines += ["", "## Choice of the layout", "",
                  "Each candidate succeeded in simulation; then it was simulated at "
                  + (f"the errors of global robustness (every radius up to {radius:g} of the "
                     "normalised design space, as rho_g weighs them)" if (radius := s.get(
                         "error_radius")) else "placement errors (Gaussian, standard "
                     f"deviation {s['verify_noise']:g} of each range)")
                  + _race_words(s.get("race_stages") or [], s.get("verify_samples"))
                  + "".join(f" The {c['moved_from']} failed its own simulation, "
                            "so the nearest of the few layouts drawn within 1/300 of it that "
                            "succeeded took its place." for c in s["verification"]
                            if c.get("moved_from"))
                  + _second_look_words(s.get("second_look"))
                  + "".join(_look_again_words(look) for look in s.get("more_looks", []))
                  + _close_in_words(s.get("close_in")), "",
                  "| candidate | success under errors | valid copies |",
                  "|---|---|---|"]
        for c in s["verification"]:
            lines.append(f"| {c['source']} | {c['success_rate']:.2f} | {c['valid_copies']} |")
    lines += [*making, "", "## Plots", "", f"![probability slice]({SLICE_PLOT})", "",
              *([] if s.get("hand") else [f"![robustness]({ROBUSTNESS_PLOT})", ""]),
              f"![exploration]({PROGRESS_PLOT})", ""]
    return "\n".join(lines)


def _second_look_words(look) -> str:
    if not look or not look["check"]:
        return ""
    c = look["check"]
    verdict = ("so the refined layout was kept" if look["kept"] else
               "so the layout chosen above was kept")
    before, refined = two_rates(c["before"], c["refined"])
    return (" Then the model was fitted again on every simulation of the run, these "
            "candidates' included, and the refinement run again: both the layout chosen and "
            f"the refined one were simulated at errors neither had met, {before} "
            f"against {refined} ({c['valid_copies'][0]} and {c['valid_copies'][1]} "
            f"valid copies), {verdict}.")


def _look_again_words(look) -> str:
    if not look["check"]:
        return " A look again moved nothing."
    c = look["check"]
    before, refined = two_rates(c["before"], c["refined"])
    return (" A look again (the model fitted on every simulation so far, refined, both "
            f"simulated at errors new to both): {before} against {refined} "
            f"({c['valid_copies'][0]} and {c['valid_copies'][1]} valid copies), so the "
            + ("refined layout was kept." if look["kept"] else "layout before it was kept."))


def _race_words(stages: list[int], planned: int | None) -> str:
    if len(stages) < 2:
        return " and the one that succeeded most often was kept."
    # the design holds verify_samples rounded up to a power of two
    end = next((n for n in stages if n >= planned), stages[-1]) if planned else stages[-1]
    past = (f" (past {end} because a candidate still racing had fewer than {end // 2} "
            "valid copies)" if stages[-1] > end else "")
    return (f": all at the first {stages[0]} errors, then twice as many and so on up to "
            f"{stages[-1]}{past}, a candidate significantly below the leader dropped after each "
            "stage (it has fewer valid copies below); of those never dropped, the one that "
            "succeeded most often was kept.")


def _exploration_lines(e) -> list[str]:
    if not e:
        return []
    stalled = ("" if e["stalled_at"] is None else f"; stalled after iteration {e['stalled_at']} "
               "(the samples it draws around stopped changing), newest samples first from then")
    return [f"- exploration: {e['samples']} samples, {e['successes']} global successes, "
            f"{e['iterations']} adaptive iterations{stalled}"]


def _robustness_lines(r: dict | None) -> list[str]:
    """The chosen layout's rho_g under placement errors, and with physical errors (physics
    branch: ``optimize --robustness N``)."""
    if not r:
        return []
    low, high = r["rho_g_interval"]
    out = [f"- rho_g under placement errors: **{r['rho_g']:.3f}** [{low:.3f}, {high:.3f}] "
           f"({r['samples_per_radius']} layouts per radius)"]
    p = r.get("physics")
    if p:
        low, high = p["rho_g_interval"]
        ranges = PhysicsRanges(**p["ranges"]).describe()
        out.append(f"- rho_g under placement plus physical errors ({ranges}): "
                   f"**{p['rho_g']:.3f}** [{low:.3f}, {high:.3f}]")
    for fig, what in ((r, "placement errors"), (p, "placement plus physical errors")):
        if fig and fig.get("failures") and (line := failures_line(fig["failures"]["close_in"])):
            out.append(f"- under {what}, {line}")
    warning = close_in_warning(r, point_to_evaluate=True)
    return out + ([f"- **warning**: {warning}"] if warning else [])


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_slice(scenario, model, x, influence, path: Path, validity=None) -> bool:
    """Predicted success through ``x`` along its two most influential parameters (one for a
    one-parameter scenario), axes in mm or degrees, contours at 50 % and 90 %. With
    ``validity`` (``(n, d) -> (n,) bool``), layouts whose parts overlap are greyed and named:
    the model never saw one, so its colour there means nothing, and a layout against such
    a region is pushed against a part, not outside the 90 % contour by chance. Returns
    whether the layout sits against such a region (its legend says so)."""
    from rgmcad.scene.design_space import bounds

    plt = _pyplot()
    low, high = bounds(scenario)
    order = np.argsort(-np.asarray(influence), kind="stable")
    fig, ax = plt.subplots(figsize=(5.5, 4.5), dpi=120)
    t = np.linspace(0.0, 1.0, 81)
    against = False
    if len(x) == 1:
        k, unit = user_scale(scenario.free[0])
        span = (low[0] + t * (high[0] - low[0])) * k
        ax.plot(span, model.success_proba(t[:, None]))
        ax.axvline((low[0] + x[0] * (high[0] - low[0])) * k, color="k", ls="--", label="layout")
        ax.set_xlabel(f"{scenario.free[0].name} ({unit})")
        ax.set_ylabel("predicted P(success)")
        ax.set_ylim(0, 1.02)
        ax.legend(fontsize=8)
    else:
        i, j = (int(v) for v in order[:2])
        (ki, ui), (kj, uj) = user_scale(scenario.free[i]), user_scale(scenario.free[j])
        A, B = np.meshgrid(t, t)
        P = np.repeat(np.asarray(x, float)[None, :], A.size, axis=0)
        P[:, i], P[:, j] = A.ravel(), B.ravel()
        Z = model.success_proba(P).reshape(A.shape)
        U, V = (low[i] + A * (high[i] - low[i])) * ki, (low[j] + B * (high[j] - low[j])) * kj
        im = ax.pcolormesh(U, V, Z, vmin=0, vmax=1, cmap="viridis", shading="gouraud")
        bad = np.zeros(Z.shape, bool)
        if validity is not None:  # the drawn layouts: 6,561 tests, about 0.1 s on simple
            bad = ~np.asarray(validity(P), bool).reshape(A.shape)
        if bad.any():
            step = t[1] - t[0]  # each tested layout stands for the cell around it
            edges = np.concatenate([[0.0], (t[:-1] + t[1:]) / 2, [1.0]])
            Ue = (low[i] + edges * (high[i] - low[i])) * ki
            Ve = (low[j] + edges * (high[j] - low[j])) * kj
            ax.pcolormesh(Ue, Ve, np.where(bad, 1.0, np.nan), cmap="Greys", vmin=0, vmax=1.6,
                          shading="flat")
            ax.plot([], [], "s", color="0.45", label="parts overlap (not buildable)")
            ci, cj = (int(round(v / step)) for v in (x[i], x[j]))
            against = bool(bad[max(cj - 2, 0):cj + 3, max(ci - 2, 0):ci + 3].any())  # 2.5 %
        if np.ptp(Z[~bad]) > 0 if (~bad).any() else False:
            lines = ax.contour(U, V, np.ma.masked_array(Z, bad), levels=[0.5, 0.9], colors="w",
                               linewidths=0.9)
            ax.clabel(lines, fmt=lambda v: f"{v:.0%}", fontsize=8)
        ax.plot((low[i] + x[i] * (high[i] - low[i])) * ki,
                (low[j] + x[j] * (high[j] - low[j])) * kj, "r*", ms=12,
                label="layout (against parts that meet)" if against else "layout")
        ax.set_xlabel(f"{scenario.free[i].name} ({ui})")
        ax.set_ylabel(f"{scenario.free[j].name} ({uj})")
        fig.colorbar(im, ax=ax, label="predicted P(success)")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"{scenario.name}: success through the layout (others held)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
    return len(x) > 1 and against


def predicted_robustness(scenario, model, x, errors=ERROR_GRID, samples: int = 400,
                         seed: int = 0) -> np.ndarray:
    """(k,) mean predicted success when every free parameter is placed with a Gaussian error
    of standard deviation ``errors[k]`` (mm for positions, degrees for angles) around ``x``
    (d,) normalised. Layouts pushed out of the design space are clipped to its border."""
    from rgmcad.scene.design_space import bounds

    low, high = bounds(scenario)
    per_unit = np.array([1.0 / (user_scale(f)[0] * (high[j] - low[j]))
                         for j, f in enumerate(scenario.free)])  # user unit -> normalised
    noise = np.random.default_rng(seed).standard_normal((samples, len(x)))
    out = np.empty(len(errors))
    for k, sigma in enumerate(errors):
        X = np.clip(np.asarray(x, float) + noise * sigma * per_unit, 0.0, 1.0)
        out[k] = float(np.mean(model.success_proba(X)))
    return out


def plot_robustness(scenario, model, x, path: Path, errors=ERROR_GRID) -> np.ndarray:
    """Plot :func:`predicted_robustness` against the placement error; returns the curve."""
    plt = _pyplot()
    curve = predicted_robustness(scenario, model, x, errors)
    fig, ax = plt.subplots(figsize=(5.5, 4.0), dpi=120)
    ax.plot(errors, curve, "o-", ms=3, color="#2d6cdf")
    for level in (0.5, 0.9):
        ax.axhline(level * curve[0], color="0.6", lw=0.8, ls=":")
        ax.annotate(f"{level:.0%} of the layout's", (errors[-1], level * curve[0]),
                    ha="right", va="bottom", fontsize=7, color="0.4")
    ax.set_xlabel("placement error, standard deviation (mm for positions, degrees for angles)",
                  fontsize=8)
    ax.set_ylabel("predicted P(success)")
    ax.set_ylim(0, 1.02)
    ax.set_xlim(errors[0], errors[-1])
    ax.grid(alpha=0.3)
    ax.set_title(f"{scenario.name}: success when parts are placed by hand", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)
    return curve


def plot_progress(result, path: Path) -> None:
    """Successful simulations over simulations, one coloured stretch per stage (exploration,
    active learning of each event), with each stage's success count."""
    plt = _pyplot()
    success = np.array([lab.success for lab in result.labels], float)
    stages = list(result.stages)
    total = np.cumsum(success)
    idx = np.arange(1, len(success) + 1)
    fig, ax = plt.subplots(figsize=(7, 4), dpi=120)
    colors = plt.get_cmap("tab10")
    for n, stage in enumerate(dict.fromkeys(stages)):
        m = np.array([s == stage for s in stages])
        where = np.flatnonzero(m)
        lo, hi = where[0], where[-1] + 1
        ax.axvspan(lo + 0.5, hi + 0.5, color=colors(n % 10), alpha=0.12, lw=0)
        joined = max(lo - 1, 0)  # from the previous stage's last point
        ax.plot(idx[joined:hi], total[joined:hi], color=colors(n % 10), lw=2,
                label=f"{stage}: {int(success[m].sum())} of {int(m.sum())} succeeded")
    ax.set_xlabel("simulation")
    ax.set_ylabel("successful simulations so far")
    ax.set_xlim(0.5, max(len(idx), 1) + 0.5)
    ax.set_ylim(0, max(total[-1] if len(total) else 0, 1) * 1.08)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    ax.set_title("exploration and active learning: whole-chain successes", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
    plt.close(fig)


def _close_in_words(close_in: dict | None) -> str:
    """report.md's account of the knife-edge screen (``close_in_copies``), when it acted."""
    if not close_in:
        return ""
    words = (f" Last, the layout to hand out had to succeed at {close_in['copies']} layouts "
             "within 1/300 of itself (a knife-edge screen): ")
    if not close_in["passed_over"]:
        return words + "it did."
    return words + (f"{' and '.join(close_in['passed_over'])} did not, so "
                    f"{close_in['kept']} was handed out instead.")


def count_line(summary: dict) -> str:
    """What the run simulated, in how long; a run learnt at the corners (``worlds``)
    simulated each layout once per world."""
    r = summary.get("robustness") or {}  # the rho_g estimate's, both kinds of error
    estimate = r.get("simulations", 0) + (r.get("physics") or {}).get("simulations", 0)
    builds = sum(summary["simulations_by_stage"].get(k, 0) for k in ("choice by hand", "hand"))
    extra = (f" and {estimate} for the rho_g estimate" if estimate else "") + (
        f" and {builds} builds by hand" if builds else "")
    n, worlds = summary["simulations"], summary.get("worlds", 1)
    counted, both = f"{n} simulations", ""
    if worlds > 1:
        counted = f"{n} layouts simulated in {worlds} physical worlds each, {n * worlds} simulations"
        both = " in both" if worlds == 2 else f" in all {worlds}"
    return (f"{counted} ({summary['successes']} successes{both}, {summary['replayed']} "
            f"replayed){extra} in {summary['wall_time']:.0f} s")
