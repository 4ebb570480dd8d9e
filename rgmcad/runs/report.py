"""What a finished optimisation run shows: ``report.md`` and its two plots.

The report is markdown written from the run's summary (``result.json``); the plots are
matplotlib figures (Agg) of the learnt success model through the layout and of the run's
progress. :mod:`rgmcad.runs.workflow` writes them into the run directory.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["REPORT_FILE", "SLICE_PLOT", "PROGRESS_PLOT", "report_markdown", "plot_slice",
           "plot_progress"]

REPORT_FILE = "report.md"
SLICE_PLOT = "probability_slice.png"
PROGRESS_PLOT = "exploration.png"


def report_markdown(scenario, s: dict, low, high) -> str:
    """``report.md`` of a run from its summary (``result.json``); ``low``, ``high`` (d,): the
    parameters' ranges, real units."""
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
             f"evaluations, {s['optimization']['status']})",
             *_robustness_lines(s.get("robustness")), "",
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
        ranges = ", ".join(f"{k} +-{v:.0%}" for k, v in p["ranges"].items())
        out.append(f"- rho_g under placement plus physical errors ({ranges}): "
                   f"**{p['rho_g']:.3f}** [{low:.3f}, {high:.3f}]")
    return out


def plot_slice(scenario, model, x, influence, path: Path) -> None:
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


def plot_progress(result, path: Path) -> None:
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
