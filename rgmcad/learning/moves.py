"""Which coordinates of an exploration draw move away from the sample it was drawn around.

The paper's mixture draws move every coordinate. In many dimensions a draw meant to make the
next event happen then also disturbs the parts of every event that already worked, and most
draws lose ground (docs/decisions.md, "Exploration step"). Two answers, both off by default:

* :func:`few_moved`: each coordinate moves with a probability, blind to the events;
* :func:`staged`: the causal graph says which coordinates each event depends on
  (``Problem.event_dimensions``); a draw keeps its parent's values on the coordinates of the
  events the parent already achieved and moves the others, so the chain is extended from
  where it got to instead of being rebuilt at every draw.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

__all__ = ["few_moved", "staged", "free_coordinates", "event_masks"]


def few_moved(draws: np.ndarray, parents: np.ndarray, share: float,
              rng: np.random.Generator) -> np.ndarray:
    """``draws`` with each coordinate kept at its parent's value unless a coin of ``share``
    says it moves; a row whose coins all say keep moves one coordinate drawn at random."""
    moves = rng.random(draws.shape) < share
    still = np.flatnonzero(~moves.any(axis=1))
    moves[still, rng.integers(draws.shape[1], size=len(still))] = True
    return np.where(moves, draws, parents)


def free_coordinates(events: Mapping[str, bool | None],
                     event_dimensions: Mapping[str, Sequence[int]], d: int) -> np.ndarray:
    """(d,) bool: the coordinates a staged draw around a sample moves: those of no event the
    sample achieved (``events``: its label per event). None are left for a sample that
    achieved every event that has coordinates (:func:`staged` then picks one event)."""
    free = np.ones(d, dtype=bool)
    for name, achieved in events.items():
        if achieved is True:
            free[list(event_dimensions.get(name, ()))] = False
    return free


def event_masks(event_dimensions: Mapping[str, Sequence[int]], d: int) -> np.ndarray:
    """(k, d) bool: the coordinates of each event that has any."""
    masks = [np.isin(np.arange(d), list(dims)) for dims in event_dimensions.values() if dims]
    return np.array(masks, dtype=bool).reshape(-1, d)


def staged(draws: np.ndarray, parents: np.ndarray, free: np.ndarray, share: float,
           rng: np.random.Generator, masks: np.ndarray) -> np.ndarray:
    """``draws`` (n, d) around ``parents`` (n, d): a share of the rows, chosen by coins of
    ``share``, keep their parent's values outside ``free`` (n, d) bool; the other rows are
    the mixture's draws unchanged. A row whose parent did everything (no coordinate free)
    moves the coordinates of one event drawn at random among ``masks``
    (:func:`event_masks`): a success is varied one stage at a time, so its neighbours keep
    the chain whole. The coins and events are drawn for every row, so the draws that follow
    do not depend on how many rows were staged."""
    chosen = rng.random(len(draws)) < share
    pick = rng.integers(max(len(masks), 1), size=len(draws))
    if len(masks):
        free = np.where(free.any(axis=1)[:, None], free, masks[pick])
    keep = chosen[:, None] & ~free
    return np.where(keep, parents, draws)
