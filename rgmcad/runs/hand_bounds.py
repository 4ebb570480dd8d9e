"""Each printed tolerance under a hand: one parameter set at its printed bound, every part
placed by hand, and the layout still works as often as the page says.

The nominal check (:mod:`rgmcad.runs.tolerance_check`) places one parameter at its bound with
everything else exact. A maker sets that parameter at the bound and places the rest by hand,
so each printed side is simulated again under the headline's first ``samples`` builds by hand
(:mod:`rgmcad.runs.hand`, the same draws: common random numbers) and compared, build by
build, with the layout itself. Where the bound works on more than ``precision`` of those
builds fewer than the layout (the headline's precision: 1 of 32 at +-5 points), the side is
halved (rounded down to the printed 0.1) and tried again, at most ``HALVINGS`` times, then 0.
A side that loses some builds but at most 3 of 32 is not clear: it is judged on 64 instead (3
may be lost), since on a layout that works one build in three builds change sides both ways.
Sides that stop against a part ("push against") are not moved: the part rests against its
neighbour, placed by contact, not by a number.

Why not a significance test: at 32 builds a sign test lets through a bound that fails one
build in four more than the layout (simple's track.x at -7.5 mm passed it 1 to 0, then failed
14 of 48 new builds the layout survived); a bound that must lose no more than the precision
on the very builds the headline counted is a statement a maker can read.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rgmcad.runs.hand import Builds, Hand
from rgmcad.runs.tolerance_check import CheckedTolerances, printed_offsets, printed_step, sides_of
from rgmcad.scene.perturbation import PhysicsDraw, PhysicsRanges
from rgmcad.sim.run import Outcome

__all__ = ["HALVINGS", "HandBounds", "hand_at_bounds"]

HALVINGS = 3
"""Halvings of a side that keeps failing under the hand, before it is set to 0."""


@dataclass(frozen=True)
class HandBounds:
    """Result of :func:`hand_at_bounds`: ``checked`` with the sides narrowed under the hand
    (``narrowed`` marks them, as the nominal check's), and per side tried, at its final bound,
    ``(builds that worked, builds)`` against the layout's ``base`` on the same builds."""

    checked: CheckedTolerances
    narrowed: np.ndarray
    rates: dict
    base: tuple[int, int]
    precision: float
    simulations: int

    def to_json(self, scenario) -> dict:
        names = [f.name for f in scenario.free]
        rates: dict[str, dict] = {}
        for (j, k), (works, n) in sorted(self.rates.items()):
            rates.setdefault(names[j], {})["low" if k == 0 else "high"] = [works, n]
        return {"samples": self.base[1], "layout_works": self.base[0], "precision": self.precision,
                "sides": len(self.rates), "narrowed": sides_of(self.narrowed, scenario),
                "at_bounds": rates, "simulations": self.simulations}


def hand_at_bounds(checked: CheckedTolerances, x, scenario, builds: Builds, hand: Hand,
                   physics: PhysicsRanges | None, seed: int, samples: int,
                   skip: np.ndarray, precision: float = 0.05,
                   halvings: int = HALVINGS) -> HandBounds:
    """Each printed side of ``checked`` (its real offset, rounded down to 0.1 mm or 0.1
    degree) not flagged in ``skip`` (d, 2), simulated under draws ``0 .. samples - 1`` of
    ``hand`` and ``physics`` (seed ``seed``) on ``builds``, against the layout ``x``
    (normalised) on the same draws; narrowed where it works on more than ``precision`` of
    them fewer (module doc)."""
    from rgmcad.scene.design_space import bounds

    x = np.asarray(x, dtype=float)
    low, high = bounds(scenario)
    width = high - low
    step = printed_step(scenario) * width  # 0.1 mm or 0.1 degree, in real units
    draws = [PhysicsDraw(hand.ranges(physics), seed, i) for i in range(2 * samples)]
    before = builds.simulations
    slack = int(np.floor(precision * samples + 1e-9))

    def works(v, n):
        return np.array([r.outcome is Outcome.SUCCESS for r in builds(v, draws[:n])])

    def loss(ok, n):  # builds the layout survived and the bound did not, net
        return int(np.sum(base[:n] & ~ok)) - int(np.sum(~base[:n] & ok))

    base = works(x, samples)
    out, narrowed = checked.tolerances.copy(), np.zeros_like(checked.narrowed)
    pending = {s: p for s, p in printed_offsets(out, scenario).items() if p > 0 and not skip[s]}
    rates = {}
    for attempt in range(halvings + 1):
        for (j, k), offset in list(pending.items()):
            moved = x.copy()
            moved[j] += (offset if k else -offset) / width[j]
            ok = works(moved, samples)
            if 0 < loss(ok, samples) <= 2 * slack + 1:  # not clear: judged on twice the builds
                if len(base) == samples:
                    base = works(x, 2 * samples)
                ok = works(moved, 2 * samples)
            rates[j, k] = (int(ok.sum()), len(ok))
            if loss(ok, len(ok)) <= np.floor(precision * len(ok) + 1e-9):
                out[j, k] = offset / width[j]
                del pending[j, k]
                continue
            narrowed[j, k] = True
            half = np.floor(offset / step[j] / 2.0 + 1e-6) * step[j]
            if attempt == halvings or half <= 0.0:
                out[j, k] = 0.0
                del pending[j, k]
            else:
                pending[j, k] = half
    tightened = CheckedTolerances(out, checked.narrowed | narrowed,
                                  checked.simulations)
    return HandBounds(tightened, narrowed, rates, (int(base[:samples].sum()), samples), precision,
                      builds.simulations - before)
