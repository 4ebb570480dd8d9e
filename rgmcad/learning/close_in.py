"""Knife edges: does a layout succeed where a builder puts it almost exactly?

rho_g weighs its smallest radius (1/300 of every range) 1/30, so a final choice made at the
errors of global robustness can prefer a layout that works on average over large errors and
fails at a fair share of the layouts a hair from it (a ball that grazes an edge, a chain on a
tie). With ``LearningSettings.close_in_copies`` = K > 0 the layout a run hands out must
succeed at K valid layouts within 1/300 of itself; if it does not, the layout it came from
(before the second look), then the final choice's runners-up, best rated first, whichever
does first (none: it stays). docs/decisions.md, "Knife edges in the final choice".
"""

from __future__ import annotations

import numpy as np

__all__ = ["RADIUS", "close_in_sound", "first_sound"]

RADIUS = 1.0 / 300.0
"""The smallest radius of rho_g (its ``eta``), in the normalised design space."""
_STREAM = 0x4B4E_4946


def close_in_sound(x: np.ndarray, simulate, validity, n: int) -> tuple[bool, int]:
    """Whether ``x`` fails at no more than one in 16 (``n // 16``) of ``n`` valid layouts
    uniform in the ball of radius RADIUS around it (inside the cube), and the simulations
    that took. The layouts are drawn from ``x`` alone: a resumed run draws the same, and two
    calls agree. One failure in 16 is let pass: a layout that succeeds at 97 % of those
    layouts (twin_finish seed 1's, rho_g 0.547) failed the stricter screen and gave way to
    one of 0.453; a knife edge (bucket_gate seed 0's, 66 %) still fails it 99 % of the time."""
    x = np.asarray(x, dtype=float)
    rng = np.random.default_rng([_STREAM, *np.frombuffer(x.tobytes(), np.uint32)])
    step = rng.standard_normal((8 * n, len(x)))
    P = x + step * (RADIUS * rng.random(8 * n) ** (1.0 / len(x))
                    / np.linalg.norm(step, axis=1))[:, None]
    P = P[np.all((P >= 0.0) & (P <= 1.0), axis=1)]
    P = P[np.asarray(validity(P), dtype=bool)][:n] if len(P) else P
    if not len(P):
        return True, 0  # nothing valid that near: nothing to say against it
    failures = sum(not label.success for label in simulate(P))
    return failures <= len(P) // 16, len(P)


def first_sound(ranked, simulate, validity, n: int):
    """The first of ``ranked`` (candidates with an ``x``, best first) that is
    :func:`close_in_sound`, the sources of those passed over before it, and the simulations
    spent. When none is sound, the first stays and nothing counts as passed over."""
    passed_over, n_sims = [], 0
    for c in ranked:
        sound, n_close = close_in_sound(c.x, simulate, validity, n)
        n_sims += n_close
        if sound:
            return c, tuple(passed_over), n_sims
        passed_over.append(c.source)
    return ranked[0], (), n_sims
