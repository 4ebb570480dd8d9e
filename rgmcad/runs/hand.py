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
           "parse_hand", "measure_rate", "hand_curve", "hand_race", "Builds", "chosen_by_hand", "weak_links",
           "hand_figures",
           "check_precision", "CURVE_MM", "rate_text"]

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


_DROP_Z = 2.5  # a finalist this many paired standard errors below the leader is dropped


def hand_race(simulate_at: Callable[[int, Sequence[PhysicsDraw]], list[SimRecord]],
              n_candidates: int, hand: Hand, physics: PhysicsRanges | None, seed: int, *,
              first: int = 32, most: int = 320, precision: float = 0.05
              ) -> tuple[int, list[HandRate]]:
    """The candidate (index) that works most often under ``hand`` and ``physics``: all meet
    the same draws (``simulate_at(i, draws)``: candidate ``i``'s records), ``first`` of them,
    then twice as many, up to ``most``; after each stage a candidate whose paired deficit to
    the leader is over ``_DROP_Z`` standard errors is dropped, and the race stops when every
    candidate left is within ``precision`` of the leader (its paired difference plus two
    standard errors: all equally good to a maker). Of those left, the highest rate wins; a
    tie goes to the earlier candidate. Returns (winner, each candidate's rate over the draws
    it met)."""
    ranges = hand.ranges(physics)
    wins: list[list[bool]] = [[] for _ in range(n_candidates)]
    records: list[list[SimRecord]] = [[] for _ in range(n_candidates)]
    alive = list(range(n_candidates))
    target = min(first, most)
    while True:
        for i in alive:
            have = len(records[i])
            new = simulate_at(i, [PhysicsDraw(ranges, seed, k) for k in range(have, target)])
            records[i] += new
            wins[i] += [r.outcome is Outcome.SUCCESS for r in new]
        leader = max(alive, key=lambda i: (np.mean(wins[i]), -i))
        kept, close = [], True
        for i in alive:
            diff = np.asarray(wins[leader], float) - np.asarray(wins[i], float)
            se = diff.std(ddof=1) / np.sqrt(len(diff)) if len(diff) > 1 else 0.0
            if i == leader or diff.mean() <= 0.0 or (se > 0.0 and diff.mean() <= _DROP_Z * se):
                kept.append(i)
                close &= abs(diff.mean()) + 2.0 * se <= precision
        alive = kept
        if len(alive) == 1 or target >= most or close:
            break
        target = min(2 * target, most)
    winner = max(alive, key=lambda i: (np.mean(wins[i]), -i))
    return winner, [_rate(hand, physics, r) for r in records]


def chosen_by_hand(chosen: dict, builds: Builds, hand: Hand, physics: PhysicsRanges | None,
                   seed: int, settings: HandSettings) -> dict:
    """``chosen`` (:func:`~rgmcad.runs.starts.choose_layout`'s choice) replaced by the finalist
    that works most often when built by ``hand`` (:func:`hand_race`, its builds on ``builds``),
    with ``hand_choice``: each finalist's rate and the one kept."""
    finalists = chosen["finalists"]
    before = builds.simulations
    winner, rates = hand_race(lambda i, draws: builds(finalists[i]["x"], draws),
                              len(finalists), hand, physics, seed, first=settings.batch,
                              most=settings.maximum, precision=settings.precision)
    out = {**chosen, "hand_choice": {
        "candidates": [{"source": f["source"], "rate": r.rate, "interval": [r.low, r.high],
                        "samples": r.samples} for f, r in zip(finalists, rates, strict=True)],
        "kept": finalists[winner]["source"], "simulations": builds.simulations - before}}
    if winner:
        won, first = rates[winner], rates[0]
        out.update(x=finalists[winner]["x"], is_optimum=finalists[winner]["source"] == "optimum",
                   source=f"{finalists[winner]['source']}, chosen over {chosen['source']} by "
                   f"simulated builds by hand ({won.successes} of {won.samples} worked, against "
                   f"{first.successes} of {first.samples})")
    return out


@dataclass(frozen=True)
class WeakLink:
    """A part (or a run of dominoes, ``objects``) misplaced alone: how often the layout
    still works."""

    name: str
    objects: tuple[str, ...]
    rate: HandRate
    careful: HandRate | None = None  # the largest smaller hand it worked at every build

    def to_json(self) -> dict:
        return {"name": self.name, "objects": list(self.objects), **self.rate.to_json(),
                "careful": None if self.careful is None else self.careful.to_json()}


def weak_links(simulate: Simulate, groups: dict[str, list[str]], hand: Hand, seed: int, *,
               first: int = 8, most: int = 32, more: int = 5) -> list[WeakLink]:
    """Each group of ``groups`` (:func:`~rgmcad.scene.perturbation.placement_groups`)
    misplaced alone by ``hand``, the physics unperturbed: ``first`` draws each, then the
    ``more`` groups that failed most (at least once) drawn on, doubling, up to ``most``.
    Returned most fragile first (lowest rate, then most draws); groups that never failed
    last."""
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
        failures = {n: sum(r.outcome is not Outcome.SUCCESS for r in records[n]) for n in wanted}
        wanted = sorted((n for n in wanted if failures[n]), key=lambda n: -failures[n])[:more]
    links = [WeakLink(n, tuple(groups[n]), _rate(hand, None, records[n])) for n in names]
    return sorted(links, key=lambda w: (w.rate.rate, -w.rate.samples))


CAREFUL = (0.75, 0.5, 0.25)
"""Fractions of the hand tried, largest first, for a weak link's own tolerance."""


def careful_hands(simulate: Simulate, links: list[WeakLink], hand: Hand, seed: int, *,
                  top: int = 3, samples: int = 16) -> list[WeakLink]:
    """The ``top`` weak links that failed, each with the largest hand of ``CAREFUL`` (the
    heading scaled alike) at which misplacing it alone worked in all ``samples`` builds: the
    care that part needs, a tolerance by simulation for a part that may be fixed. Others
    unchanged; a link that failed at every size gets none."""
    out = list(links)
    for k, link in enumerate(links[:top]):
        if link.rate.successes == link.rate.samples:
            break
        for fraction in CAREFUL:
            small = Hand(hand.position_mm * fraction, hand.heading_deg * fraction)
            draws = [PhysicsDraw(small.ranges(None), seed, i, frozenset(link.objects))
                     for i in range(samples)]
            rate = _rate(small, None, simulate(draws))
            if rate.successes == rate.samples:
                out[k] = dataclasses.replace(link, careful=rate)
                break
    return out


class Builds:
    """Simulated builds of layouts on an executor (whose context is the scenario's), each
    (layout, draw) once: the final choice's draws of the layout it keeps are its headline's
    first draws, not simulated again. ``progress.built`` is told of each new one."""

    def __init__(self, executor, progress=None):
        self.executor, self.progress = executor, progress
        self.done: dict = {}
        self.simulations = 0

    def __call__(self, x, draws: Sequence[PhysicsDraw]) -> list[SimRecord]:
        x = np.asarray(x, dtype=float)
        key = x.tobytes()
        new = [d for d in dict.fromkeys(draws) if (key, d) not in self.done]
        for draw, record in zip(new, self.executor.map_context(
                simulate_layout_task, [(x, True, d) for d in new]), strict=True):
            self.done[key, draw] = record
            self.simulations += 1
            if self.progress is not None:
                self.progress.built(record)
        return [self.done[key, d] for d in draws]


@dataclass(frozen=True)
class HandSettings:
    """How many builds each figure of :func:`hand_figures` simulates: the headline rate in
    batches of ``batch`` (at least ``minimum``, at most ``maximum``) until its 95 % interval's
    half-width is at most ``precision``; ``curve_samples`` per size on the curve; each part
    alone ``weak_first`` times, up to ``weak_most`` where it failed; ``careful_samples`` per
    smaller hand for the weakest links (:func:`careful_hands`); ``bound_samples`` per printed
    tolerance at its bound (:mod:`rgmcad.runs.hand_bounds`; at most ``minimum``: the
    headline's first builds are the comparison)."""

    precision: float = 0.05
    batch: int = 32
    minimum: int = 64
    maximum: int = 320  # +-5.5 points at 50 %
    curve_samples: int = 24
    weak_first: int = 8
    weak_most: int = 32
    careful_samples: int = 16
    bound_samples: int = 32


HAND_SETTINGS = {"small": HandSettings(0.2, 16, 16, 16, 0, 2, 4, 0, 0),
                 "default": HandSettings()}
"""By ``optimize``'s budget (others: ``"default"``'s); ``evaluate`` uses ``"default"``. No
curve, no care for the weak links and no tolerance under the hand at ``small`` (a quick look;
0 builds: not measured)."""


def hand_figures(executor, problem: ScenarioProblem, x, hand: Hand,
                 physics: PhysicsRanges | None, seed: int,
                 settings: HandSettings = HAND_SETTINGS["default"], progress=None,
                 name: str = "layout", builds: Builds | None = None) -> dict:
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
    builds = builds or Builds(executor, progress)
    before = builds.simulations
    s = settings

    def simulate(draws):
        return builds(x, draws)

    def stage(title, total):
        if progress is not None:
            progress.stage(title, total)
        return time.perf_counter()

    start = stage(f"builds {hand.describe()}", s.maximum)
    rate = measure_rate(simulate, hand, physics, seed, precision=s.precision, batch=s.batch,
                        minimum=s.minimum, maximum=s.maximum)
    if progress is not None:
        progress.measured({"hand": rate.to_json()})
    curve_at = stage("success against hand error", max(s.curve_samples * (len(CURVE_MM) - 1), 1))
    curve = hand_curve(simulate, hand, physics, seed, known=rate, samples=s.curve_samples,
                       sizes_mm=CURVE_MM if s.curve_samples else ())
    groups = placement_groups(problem.scenario,
                              [n for n, p in problem.parts.items() if p.infinite])
    weak_at = stage("weak links", len(groups) * s.weak_first + 5 * (s.weak_most - s.weak_first)
                    + 3 * len(CAREFUL) * s.careful_samples)  # at most
    links = weak_links(simulate, groups, hand, seed, first=s.weak_first, most=s.weak_most)
    if s.careful_samples:
        links = careful_hands(simulate, links, hand, seed, samples=s.careful_samples)
    end = time.perf_counter()
    return {"hand": rate.to_json(), "hand_curve": [c.to_json() for c in curve],
            "weak_links": [w.to_json() for w in links],
            "simulations": builds.simulations - before,
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
