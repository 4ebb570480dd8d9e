"""Which samples the exploration's next mixture grows around (paper Alg. 1, step 2, and
rgmcad's rules for an exploration that stalls)."""

from __future__ import annotations

import numpy as np

__all__ = ["exploration_parents"]


def exploration_parents(
    counts: np.ndarray, n: int, newest_first: bool = False, *,
    X: np.ndarray | None = None, spacing: float = 0.0,
) -> np.ndarray:
    """Indices of the samples the next exploration mixture grows around: the ``n`` with the
    most successful events; ties at the lowest count taken go to the oldest (the paper's
    order) or, with ``newest_first`` (a stalled exploration), to the most recent.

    Why the second: with the oldest first, a draw that only equals the lowest count never
    gets in, so once the top samples stop improving every later draw is made around the same
    ``n`` points. With the newest first the mixtures follow their own latest draws and the
    population wanders over the level it reached (docs/decisions.md, "Exploration stalls").

    With ``spacing`` > 0 (and ``X``, the samples' coordinates), the samples are taken in that
    order (most events first, then newest or oldest) but one closer than ``spacing`` to a
    sample already taken waits until every sample that is not has been taken: the parents
    spread over the level they reached instead of gathering where its latest draws fell
    (docs/decisions.md, "Parents spread apart after a stall").
    """
    counts = np.asarray(counts)
    if spacing > 0 and X is not None:
        return _spaced(counts, n, newest_first, np.asarray(X, dtype=float), spacing)
    top = np.argsort(-counts, kind="stable")[: min(n, len(counts))]
    if newest_first and len(top):
        cut = counts[top[-1]]
        above = top[counts[top] > cut]
        at_cut = np.flatnonzero(counts == cut)[::-1][: len(top) - len(above)]
        top = np.concatenate([above, at_cut])
    return top


def _spaced(counts: np.ndarray, n: int, newest_first: bool, X: np.ndarray,
            spacing: float) -> np.ndarray:
    """:func:`exploration_parents` with a spacing: greedy in the order of preference, a
    sample is taken only if it lies at least ``spacing`` from every one taken before; the
    places left go to the skipped samples in the same order."""
    index = np.arange(len(counts))
    order = np.lexsort((-index if newest_first else index, -counts))
    n = min(n, len(counts))
    chosen = np.empty((n, X.shape[1]))
    taken: list[int] = []
    skipped: list[int] = []
    for i in order:
        if len(taken) == n:
            break
        gaps = np.sum((chosen[: len(taken)] - X[i]) ** 2, axis=1)
        if len(taken) and gaps.min() < spacing**2:
            skipped.append(int(i))
            continue
        chosen[len(taken)] = X[i]
        taken.append(int(i))
    taken.extend(skipped[: n - len(taken)])
    return np.asarray(taken[:n], dtype=int)
