"""How a person reads the figures of :mod:`rgmcad.runs.hand`: the headline, the line on a
template's cover, the curve as a table and a plot, the weak links, the report's section."""

from __future__ import annotations

from rgmcad.runs.hand import rate_text
from rgmcad.runs.robustness import save_plot
from rgmcad.scene.perturbation import PhysicsRanges

__all__ = ["hand_headline", "hand_note", "hand_table", "weak_link_lines", "hand_markdown",
           "plot_hand"]


def hand_headline(figures: dict) -> str:
    """The headline of :func:`hand_figures`' output: "works 93 % [90, 95] of the time when
    each part is placed within +-2 mm and +-2 degrees, with friction +-20%, ... (297 of 320
    builds simulated)"."""
    h = figures["hand"]
    physics = "" if h["physics"] is None else \
        f", with {PhysicsRanges(**h['physics']).describe()}"
    return (f"works {rate_text(h['rate'], *h['interval'])} of the time when each part is "
            f"placed within +-{h['position_mm']:g} mm and +-{h['heading_deg']:g} degrees"
            f"{physics} ({h['successes']} of {h['samples']} builds simulated)")


def hand_note(figures: dict) -> str:
    """The headline in a line a template's cover has room for."""
    h = figures["hand"]
    return (f"built by hand: works {rate_text(h['rate'], *h['interval'])} of the time with "
            f"each part within +-{h['position_mm']:g} mm and +-{h['heading_deg']:g} deg"
            + ("" if h["physics"] is None else ", physical errors on")
            + f" ({h['samples']} builds simulated)")


def hand_table(figures: dict) -> list[tuple[str, str, str]]:
    """The curve as rows (hand's error, works, builds)."""
    return [(f"+-{c['position_mm']:.1f} mm, +-{c['heading_deg']:.1f} deg",
             rate_text(c["rate"], *c["interval"]), f"of {c['samples']}")
            for c in figures["hand_curve"]]


def weak_link_lines(figures: dict, most: int = 5) -> list[str]:
    """The weak links, most fragile first, or one line saying there are none."""
    h, links = figures["hand"], figures["weak_links"]
    weak = [w for w in links if w["successes"] < w["samples"]]
    if not weak:
        return [f"weak links: none; no part misplaced alone broke the machine "
                f"({sum(w['samples'] for w in links)} simulations)"]
    out = [f"weak links (one part misplaced within +-{h['position_mm']:g} mm and "
           f"+-{h['heading_deg']:g} deg, the rest exact, physics unperturbed):"]
    for w in weak[:most]:
        many = f" ({len(w['objects'])} parts)" if len(w["objects"]) > 1 else ""
        care = w.get("careful")
        out.append(f"  {w['name']}{many}: fails {w['samples'] - w['successes']} of "
                   f"{w['samples']}" + ("" if not care else
                                        f"; within +-{care['position_mm']:.1f} mm and "
                                        f"+-{care['heading_deg']:.1f} deg it worked "
                                        f"{care['successes']} of {care['samples']}"))
    if len(weak) > most:
        out.append(f"  and {len(weak) - most} more")
    return out


def hand_markdown(figures: dict | None, plot: str) -> list[str]:
    """The "Built by hand" section of a run's report (none without figures)."""
    if not figures:
        return []
    lines = ["", "## Built by hand", "",
             "Every part (free or fixed, each domino too) placed at random around its printed "
             "place and simulated, the physical errors on top; a part that would land inside "
             f"another is placed again. The layout {hand_headline(figures)}; "
             "`rgmcad evaluate --hand` measures another hand.", "",
             "| each part within | works (95 % interval) | builds |", "|---|---|---|"]
    lines += [f"| {a} | {b} | {c[3:]} |" for a, b, c in hand_table(figures)]
    lines += ["", *(f"- {line.strip()}" if line.startswith("  ") else line
                    for line in weak_link_lines(figures)), "", f"![built by hand]({plot})"]
    return lines


def plot_hand(figures: dict, path, title: str = "") -> None:
    """Success rate against the size of a hand's position errors (heading in proportion),
    with 95 % bands; the measured hand marked (matplotlib, Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curve = figures["hand_curve"]
    mm = [c["position_mm"] for c in curve]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=120)
    (line,) = ax.plot(mm, [c["rate"] * 100 for c in curve], marker="o")
    ax.fill_between(mm, [c["interval"][0] * 100 for c in curve],
                    [c["interval"][1] * 100 for c in curve], color=line.get_color(), alpha=0.2,
                    lw=0)
    head = figures["hand"]
    ax.errorbar([head["position_mm"]], [head["rate"] * 100], fmt="s", color="black",
                yerr=[[100 * (head["rate"] - head["interval"][0])],
                      [100 * (head["interval"][1] - head["rate"])]],
                label=f"+-{head['position_mm']:g} mm, +-{head['heading_deg']:g} deg: "
                      f"{head['samples']} builds")
    degrees = head["heading_deg"] / head["position_mm"] if head["position_mm"] else 0.0
    ax.set_xlabel(f"hand's error: +- mm along x and y (and +-{degrees:.2g} deg per mm)")
    ax.set_ylabel("works, % of builds")
    ax.set_ylim(0, 102)
    ax.set_xlim(0, max(mm))
    save_plot(fig, ax, path, title, "lower left")

