"""How often does a layout work when a person builds it? Success rates under a hand's
placement errors, in millimetres and degrees, by simulation.

A :class:`Hand` says how far from its printed place a person puts each part: every
hand-placed object (:func:`~rgmcad.scene.perturbation.hand_placed_objects`: free parts, fixed
parts, each domino of a run) moved uniformly within ``+-position_mm`` along its parent's x and
y and ``+-heading_deg`` about its z, on top of the physical errors (friction, mass,
restitution) when they are on. Nothing is normalised: widening a free parameter's range in
the file changes none of these figures.

* :func:`measure_rate`: one success rate with its Wilson 95 % interval, sequential: batches of
  draws until the interval's half-width is at most ``precision`` (or the most draws allowed).
  Draw ``k`` of a layout places every part as draw ``k`` of any other layout does (common
  random numbers, :class:`~rgmcad.scene.perturbation.PhysicsDraw`), so two layouts measured
  with the same seed meet the same hands.
* :func:`hand_curve`: success against the size of the hand's errors, 0 to 10 mm, the heading
  scaled with the position (the ratio of the hand measured).
* :func:`weak_links`: each part (a domino run as one) misplaced alone, everything else exact
  and the physics the scenario's: which part's error breaks the machine, by simulation.
  Parts that never fail in the first draws get no more; those that do get more, to rank them.

Results depend on the seed and the settings only, never on the number of workers or on time.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rgmcad.errors import UsageError
from rgmcad.runs.problem import ScenarioProblem, SimRecord, simulate_layout_task
from rgmcad.runs.robustness import first_failure, wilson_interval
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges, placement_groups
from rgmcad.sim.run import Outcome

__all__ = ["Hand", "DEFAULT_HAND", "HandRate", "WeakLink", "HandSettings", "HAND_SETTINGS",
           "parse_hand", "measure_rate", "hand_curve", "weak_links", "hand_figures", "plot_hand",
           "check_precision", "CURVE_MM", "rate_text", "hand_headline", "hand_table",
           "weak_link_lines", "hand_markdown", "hand_note"]

CURVE_MM = (0.0, 1.0, 2.0, 3.0, 5.0, 7.0, 10.0)
"""Sizes of a hand's position errors (mm) on the curve."""
_MAX_MM, _MAX_DEG = 50.0, 10.0


@dataclass(frozen=True)
class Hand:
    """How far from its printed place a person puts each part: uniformly within
    ``+-position_mm`` along x and y and ``+-heading_deg`` about the vertical."""

    position_mm: float = 2.0
    heading_deg: float = 2.0

    def __post_init__(self):
        for key, value, high in (("mm", self.position_mm, _MAX_MM),
                                 ("deg", self.heading_deg, _MAX_DEG)):
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and 0.0 <= value <= high):
                raise UsageError("--hand", key, f"expected 0 to {high:g}, got {value!r}")

    def ranges(self, physics: PhysicsRanges | None) -> PhysicsRanges:
        """The perturbation to simulate: this hand on top of ``physics`` (None: the scenario's
        physics, unperturbed)."""
        base = physics or PhysicsRanges(friction=0.0, mass=0.0, restitution=0.0)
        return dataclasses.replace(base, position=self.position_mm / 1000.0,
                                   heading=self.heading_deg)

    def scaled(self, position_mm: float) -> Hand:
        """A hand with position errors of ``position_mm``, its heading errors in the same
        ratio (degrees per millimetre) as this hand's."""
        if self.position_mm == 0.0:
            return Hand(position_mm, self.heading_deg)
        return Hand(position_mm, min(self.heading_deg * position_mm / self.position_mm,
                                     _MAX_DEG))

    def describe(self) -> str:
        return f"within +-{self.position_mm:g} mm and +-{self.heading_deg:g} deg"

    def to_json(self) -> dict:
        return {"position_mm": self.position_mm, "heading_deg": self.heading_deg}


DEFAULT_HAND = Hand()


def parse_hand(text: str, where: str = "--hand") -> Hand:
    """``"2mm,2deg"`` (either may be left out; units required) -> :class:`Hand`."""
    given = {}
    for item in text.split(","):
        item = item.strip().lower()
        unit = next((u for u in ("mm", "deg") if item.endswith(u)), None)
        try:
            value = float(item[: -len(unit)]) if unit else None
        except ValueError:
            value = None
        if value is None:
            raise UsageError(where, repr(item), "expected e.g. '2mm,2deg' (millimetres along x "
                             "and y, degrees about the vertical)")
        given["position_mm" if unit == "mm" else "heading_deg"] = value
    try:
        return Hand(**{**DEFAULT_HAND.to_json(), **given})
    except UsageError as error:
        raise UsageError(where, error.key, error.message) from None


@dataclass(frozen=True)
class HandRate:
    """A success rate under a hand's (and physical) errors.

    Attributes
    ----------
    hand : the hand's errors.
    physics : the physical ranges on top (None: off).
    successes, samples : successful draws and draws simulated.
    low, high : Wilson 95 % interval of the rate.
    failed : {event: draws that failed there first}, most frequent first.
    """

    hand: Hand
    physics: PhysicsRanges | None
    successes: int
    samples: int
    low: float
    high: float
    failed: dict

    @property
    def rate(self) -> float:
        return self.successes / self.samples if self.samples else 0.0

    def to_json(self) -> dict:
        return {**self.hand.to_json(),
                "physics": None if self.physics is None else self.physics.to_json(),
                "rate": self.rate, "interval": [self.low, self.high],
                "successes": self.successes, "samples": self.samples, "failed": self.failed}


def rate_text(rate: float, low: float, high: float) -> str:
    """``93 % [90, 95]``: whole percent, the interval rounded outwards."""
    return (f"{math.floor(rate * 100 + 0.5):.0f} % [{math.floor(low * 100):.0f}, "
            f"{math.ceil(high * 100):.0f}]")


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
        out.append(f"  {w['name']}{many}: fails {w['samples'] - w['successes']} of "
                   f"{w['samples']}")
    if len(weak) > most:
        out.append(f"  and {len(weak) - most} more")
    return out


Simulate = Callable[[Sequence[PhysicsDraw]], list[SimRecord]]


def _rate(hand, physics, records) -> HandRate:
    wins = sum(r.outcome is Outcome.SUCCESS for r in records)
    low, high = wilson_interval(wins, len(records))
    failed: dict[str, int] = {}
    for record in records:
        if (event := first_failure(record)) is not None:
            failed[event] = failed.get(event, 0) + 1
    failed = dict(sorted(failed.items(), key=lambda kv: (-kv[1], kv[0])))
    return HandRate(hand, physics, wins, len(records), float(low), float(high), failed)


def measure_rate(simulate: Simulate, hand: Hand, physics: PhysicsRanges | None, seed: int, *,
                 precision: float = 0.05, batch: int = 32, minimum: int = 64,
                 maximum: int = 320, moved: frozenset[str] | None = None) -> HandRate:
    """The success rate of one layout under ``hand`` (and ``physics``): draws ``0, 1, ...`` of
    ``seed`` in batches of ``batch``, at least ``minimum`` and at most ``maximum``, until the
    Wilson 95 % interval's half-width is at most ``precision``. ``simulate(draws)`` returns one
    record per draw. ``moved``: only those objects misplaced (:class:`PhysicsDraw`)."""
    ranges = hand.ranges(physics)
    records: list[SimRecord] = []
    while len(records) < maximum:
        size = min(batch, maximum - len(records))
        records += simulate([PhysicsDraw(ranges, seed, len(records) + k, moved)
                             for k in range(size)])
        rate = _rate(hand, physics, records)
        if len(records) >= minimum and (rate.high - rate.low) / 2 <= precision:
            break
    return _rate(hand, physics, records)


def hand_curve(simulate: Simulate, hand: Hand, physics: PhysicsRanges | None, seed: int, *,
               sizes_mm: Sequence[float] = CURVE_MM, samples: int = 24,
               known: HandRate | None = None) -> list[HandRate]:
    """Success against the size of a hand's errors: for each position error in ``sizes_mm``
    (the heading in ``hand``'s ratio), ``samples`` draws of ``seed`` (the same draws at every
    size, scaled); a size already measured (``known``) is taken from it."""
    out = []
    for size in sorted({*sizes_mm, *([known.hand.position_mm] if known else [])}):
        if known is not None and size == known.hand.position_mm:
            out.append(known)
            continue
        scaled = hand.scaled(size)
        ranges = scaled.ranges(physics)
        out.append(_rate(scaled, physics, simulate(
            [PhysicsDraw(ranges, seed, k) for k in range(samples)])))
    return out


@dataclass(frozen=True)
class WeakLink:
    """A part (or a run of dominoes, ``objects``) misplaced alone: how often the layout
    still works."""

    name: str
    objects: tuple[str, ...]
    rate: HandRate

    def to_json(self) -> dict:
        return {"name": self.name, "objects": list(self.objects), **self.rate.to_json()}


def weak_links(simulate: Simulate, groups: dict[str, list[str]], hand: Hand, seed: int, *,
               first: int = 8, most: int = 32) -> list[WeakLink]:
    """Each group of ``groups`` (:func:`~rgmcad.scene.perturbation.placement_groups`)
    misplaced alone by ``hand``, the physics unperturbed: ``first`` draws each, then the
    groups that failed at least once drawn on, doubling, up to ``most``. Returned most
    fragile first (lowest rate, then most draws); groups that never failed last."""
    names = list(groups)
    records: dict[str, list[SimRecord]] = {name: [] for name in names}
    ranges = hand.ranges(None)
    target, wanted = first, names
    while wanted:
        draws = []
        for name in wanted:
            have = len(records[name])
            draws += [(name, PhysicsDraw(ranges, seed, have + k, frozenset(groups[name])))
                      for k in range(target - have)]
        for (name, _), record in zip(draws, simulate([d for _, d in draws]), strict=True):
            records[name].append(record)
        if target >= most:
            break
        target = min(2 * target, most)
        wanted = [n for n in wanted if any(r.outcome is not Outcome.SUCCESS for r in records[n])]
    links = [WeakLink(n, tuple(groups[n]), _rate(hand, None, records[n])) for n in names]
    return sorted(links, key=lambda w: (w.rate.rate, -w.rate.samples))


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


@dataclass(frozen=True)
class HandSettings:
    """How many builds each figure of :func:`hand_figures` simulates: the headline rate in
    batches of ``batch`` (at least ``minimum``, at most ``maximum``) until its 95 % interval's
    half-width is at most ``precision``; ``curve_samples`` per size on the curve; each part
    alone ``weak_first`` times, up to ``weak_most`` where it failed."""

    precision: float = 0.05
    batch: int = 32
    minimum: int = 64
    maximum: int = 320  # +-5.5 points at 50 %
    curve_samples: int = 24
    weak_first: int = 8
    weak_most: int = 32


HAND_SETTINGS = {"tiny": HandSettings(0.2, 8, 8, 16, 4, 2, 4),
                 "small": HandSettings(0.1, 16, 16, 96, 8, 4, 8),
                 "default": HandSettings()}
"""By ``optimize``'s budget (others: ``"default"``'s); ``evaluate`` uses ``"default"``."""


def hand_figures(executor, problem: ScenarioProblem, x, hand: Hand,
                 physics: PhysicsRanges | None, seed: int,
                 settings: HandSettings = HAND_SETTINGS["default"], progress=None,
                 name: str = "layout") -> dict:
    """The figures of this module for the layout ``x`` (normalised, valid), simulated on
    ``executor`` (whose context is ``problem``'s), progress told to ``progress`` (a
    :class:`~rgmcad.runs.workflow.RunProgress`):

    ``{"hand": HandRate JSON, "hand_curve": [HandRate JSON, ...], "weak_links": [WeakLink
    JSON, ...], "simulations": n, "precision": settings.precision, "seconds": {figure: s}}``.
    """
    x = np.asarray(x, dtype=float)
    if not bool(problem.validity(x[None])[0]):
        raise UsageError("--layout", name, "its parts overlap where designed, so no hand can "
                         "place it; `rgmcad simulate` names the parts")
    count = [0]
    s = settings

    def simulate(draws):
        out = []
        for record in executor.map_context(simulate_layout_task, [(x, True, d) for d in draws]):
            out.append(record)
            if progress is not None:
                progress.built(record)
        count[0] += len(out)
        return out

    def stage(title, total):
        if progress is not None:
            progress.stage(title, total)
        return time.perf_counter()

    start = stage(f"builds {hand.describe()}", s.maximum)
    rate = measure_rate(simulate, hand, physics, seed, precision=s.precision, batch=s.batch,
                        minimum=s.minimum, maximum=s.maximum)
    curve_at = stage("success against hand error", s.curve_samples * (len(CURVE_MM) - 1))
    curve = hand_curve(simulate, hand, physics, seed, known=rate, samples=s.curve_samples)
    groups = placement_groups(problem.scenario,
                              [n for n, p in problem.parts.items() if p.infinite])
    weak_at = stage("weak links", len(groups) * s.weak_most)
    links = weak_links(simulate, groups, hand, seed, first=s.weak_first, most=s.weak_most)
    end = time.perf_counter()
    return {"hand": rate.to_json(), "hand_curve": [c.to_json() for c in curve],
            "weak_links": [w.to_json() for w in links], "simulations": count[0],
            "precision": s.precision,
            "seconds": {"hand": curve_at - start, "hand_curve": weak_at - curve_at,
                        "weak_links": end - weak_at}}


def check_precision(value, where: str) -> float:
    """A half-width of a 95 % interval, 0.005 to 0.5."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not 0.005 <= value <= 0.5:
        raise UsageError(where, str(value), "expected a half-width from 0.005 to 0.5 (0.05: "
                         "the rate to +-5 points)")
    return float(value)


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
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)

