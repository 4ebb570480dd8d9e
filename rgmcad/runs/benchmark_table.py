"""The benchmark's table (``benchmark.json``, ``benchmark.md``) and figure
(``robustness.png``) from the trials' evaluations (:mod:`rgmcad.runs.benchmark`): means and
standard errors of rho_g per row, the paired difference of each row to ours with its t-test,
and how many trials or layouts per radius a difference of ``DETECT`` would need.
"""

from __future__ import annotations

import numpy as np

from rgmcad.files import naming

__all__ = ["DETECT", "build_table", "table_rows", "power_note", "table_markdown", "plot_benchmark"]


def _mean_of(values) -> float | None:
    values = list(values)
    return None if None in values else float(np.mean(values))


def _mean_se(v) -> tuple[float, float | None]:
    v = np.asarray(v, dtype=float)
    se = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else None
    return float(v.mean()), se


def build_table(name, methods, labels, seeds, budget, samples, found, evaluations) -> dict:
    """The table (``benchmark.json``'s content less its settings) of the rows ``methods``
    (``labels``: their names in the table); ``found[m]``: the trials' results, ``evaluations[m]``
    their evaluations, one per seed."""
    rows = []
    for m in methods:
        rho_g = [e["rho_g"] for e in evaluations[m]]
        curves = np.array([e["rho"] for e in evaluations[m]])
        mean, se = _mean_se(rho_g)
        row = {"method": m, "label": labels[m], "trials": len(rho_g), "rho_g_mean": mean,
               "rho_g_se": se, "rho_g": rho_g,
               "rho_l_mean": curves.mean(axis=0).tolist(),
               "rho_l_se": (curves.std(axis=0, ddof=1) / np.sqrt(len(curves))).tolist()
               if len(curves) > 1 else [None] * curves.shape[1],
               # None for a given layout (``--reference``): it cost no simulation
               **{f"{k}_mean": _mean_of(t[k] for t in found[m])
                  for k in ("simulations", "budget_sims", "time_s")},
               "vectors": [t["vector"] for t in found[m]]}
        ours = [e["rho_g"] for e in evaluations.get("ours", [])]
        if ours and m != "ours" and len(rho_g) > 1:
            row["paired_vs_ours"] = _paired(rho_g, ours)
        if all(e.get("physics") for e in evaluations[m]):
            phys = [e["physics"]["rho_g"] for e in evaluations[m]]
            row["physics_rho_g"] = phys
            row["physics_rho_g_mean"], row["physics_rho_g_se"] = _mean_se(phys)
            row["physics_rho_l_mean"] = np.mean([e["physics"]["rho"] for e in evaluations[m]],
                                                axis=0).tolist()
            ours = [(e.get("physics") or {}).get("rho_g") for e in evaluations.get("ours", [])]
            if ours and None not in ours and m != "ours" and len(phys) > 1:
                row["physics_paired_vs_ours"] = _paired(phys, ours)
        rows.append(row)
    eps = evaluations[methods[0]][0]["eps"]
    return {"scenario": name, "budget_sims": budget, "seeds": seeds,
            "samples_per_radius": samples, "eps": eps, "rows": rows,
            "evaluation_power": _evaluation_power(evaluations, samples)}


def _paired(rho_g, ours) -> dict:
    """Mean difference (this method minus ours) with its s.e. and the paired t-test."""
    from scipy.stats import ttest_rel

    diff = np.asarray(rho_g) - np.asarray(ours)
    dm, dse = _mean_se(diff)
    p = float(ttest_rel(rho_g, ours).pvalue)
    return {"mean_difference": dm, "se": dse, "p_value": None if np.isnan(p) else p,
            "trials_for_0.05": _needed(float(diff.std(ddof=1)), 1)}


# two-sided 5 % test with 80 % power, normal approximation: z_0.975 + z_0.8
_Z_POWER = 1.959964 + 0.841621
DETECT = 0.05
"""The rho_g difference the power figures are for."""


def _needed(sd_one: float, per: float) -> int:
    """How many units (trials, or samples per radius) make a difference of ``DETECT``
    detectable, when ``per`` units give a spread ``sd_one`` of the difference."""
    return max(2, int(np.ceil(per * (_Z_POWER * sd_one / DETECT) ** 2)))


def _evaluation_power(evaluations: dict, samples: int) -> dict:
    """One layout's evaluation s.e. of rho_g (from the intervals), and the samples per radius
    that would let two layouts' evaluations alone separate ``DETECT``."""
    se = float(np.mean([(e["rho_g_interval"][1] - e["rho_g_interval"][0]) / (2 * 1.959964)
                        for es in evaluations.values() for e in es]))
    return {"rho_g_se": se, "samples_for_0.05": _needed(np.sqrt(2) * se, samples)}


def _num(v, f="{:.3f}"):
    return "n/a" if v is None or (isinstance(v, float) and np.isnan(v)) else f.format(v)


def _diff(pair) -> str:
    if pair is None:
        return ""
    need = pair.get("trials_for_0.05")
    return (f"{pair['mean_difference']:+.3f} +- {_num(pair['se'])} (p "
            f"{_num(pair['p_value'], '{:.2g}')}" + (f"; {need} trials for 0.05)" if need
                                                     else ")"))


def table_rows(table: dict) -> list[str]:
    """The table's Markdown rows (head included), one per method or given layout."""
    phys = table.get("physics")
    head = "| method | trials | rho_g (mean +- s.e.) | paired diff. vs ours (p) | "
    rule = "|---|---|---|---|"
    if phys:
        head += "rho_g placement + physics | paired diff. vs ours (p) | "
        rule += "---|---|"
    lines = [head + "simulations used | time (s, one core) |", rule + "---|---|"]
    for r in table["rows"]:
        cells = f"| {r['label']} | {r['trials']} | {r['rho_g_mean']:.3f} +- " \
                f"{_num(r['rho_g_se'])} | {_diff(r.get('paired_vs_ours'))} | "
        if phys:
            cells += (f"{_num(r.get('physics_rho_g_mean'))} +- "
                      f"{_num(r.get('physics_rho_g_se'))} | "
                      f"{_diff(r.get('physics_paired_vs_ours'))} | ")
        lines.append(cells + f"{_num(r['simulations_mean'], '{:.0f}')} | "
                     f"{_num(r['time_s_mean'], '{:.1f}')} |")
    return lines


def power_note(table: dict) -> str:
    """What the evaluations and trials can tell apart (empty if the table has no power)."""
    power = table.get("evaluation_power")
    if not power:
        return ""
    return (f"Power for a difference of {DETECT} (two-sided 5 %, 80 % power, normal "
            f"approximation): one layout's rho_g is estimated with s.e. "
            f"{power['rho_g_se']:.3f} at {table['samples_per_radius']} layouts per "
            f"radius, so two layouts {DETECT} apart are told apart by their evaluations "
            f"with about {power['samples_for_0.05']} per radius; \"trials for "
            f"{DETECT}\" is the number of seeds the paired test needs at the spread of "
            "the differences observed.")


def table_markdown(table: dict) -> str:
    """The table as Markdown, like the paper's Table 1."""
    phys = table.get("physics")
    lines = [f"# Benchmark: {table['scenario']}", "",
             f"B = {table['budget_sims']} simulations per method run (every simulation ours "
             f"ran, its final choice included; validity tests not counted); "
             f"{len(table['seeds'])} trial(s), seeds {table['seeds'][0]}.."
             f"{table['seeds'][-1]}; rho_l from {table['samples_per_radius']} valid layouts "
             "per radius, 30 radii, common random numbers across methods.", ""]
    if phys:
        lines += ["Placement + physics: the same layouts simulated with physical errors "
                  f"(friction +-{phys['friction']:.0%}, mass +-{phys['mass']:.0%}, "
                  f"restitution +-{phys['restitution']:.0%}), common draws across methods.", ""]
    if table.get("earlier_rows"):
        lines += ["Rows finished by earlier calls in this folder under the same protocol (the "
                  "same scenario file, budget, trials, samples and physical errors), not run "
                  "again: " + ", ".join(table["earlier_rows"]) + ".", ""]
    lines += table_rows(table)
    note = power_note(table)
    if note:
        lines += ["", note]
    return "\n".join(lines) + "\n"


def plot_benchmark(table: dict, path) -> None:
    """Mean rho_l curves with standard-error bands, one per method (like Fig. 15)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    eps = np.asarray(table["eps"])
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    for r in table["rows"]:
        mean = np.asarray(r["rho_l_mean"])
        se = np.nan_to_num(np.asarray(r["rho_l_se"], dtype=float))
        (line,) = ax.plot(eps, mean, label=f"{r['label']} (rho_g {r['rho_g_mean']:.3f})")
        ax.fill_between(eps, mean - se, mean + se, color=line.get_color(), alpha=0.2, lw=0)
        if r.get("physics_rho_l_mean") is not None:
            ax.plot(eps, r["physics_rho_l_mean"], ls="--", color=line.get_color(),
                    label=f"  + physics (rho_g {r['physics_rho_g_mean']:.3f})")
    ax.set_xlabel("eps (radius in the normalised design space)")
    ax.set_ylabel("local robustness rho_l (mean over trials)")
    ax.set_xlim(0, float(eps.max()))
    ax.set_ylim(0, 1.02)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(f"{table['scenario']}: B = {table['budget_sims']}, "
                 f"{len(table['seeds'])} trial(s)", fontsize=10)
    fig.tight_layout()
    with naming(path):
        fig.savefig(path)
    plt.close(fig)
