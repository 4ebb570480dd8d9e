"""Samplers of the design space and the initial exploration (paper section 5.1, Alg. 1).

Every sampler draws candidates first and tests their validity in order, keeping the first
valid ones, as the authors' ``find_physically_valid_samples`` does (SPEC section 5.1).
Invalid layouts are never simulated.
"""

from __future__ import annotations

import logging
import warnings
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.stats import qmc

from .moves import event_masks, few_moved, free_coordinates, staged
from .oracles import Label, Problem
from .parents import exploration_parents
from .settings import LearningSettings

__all__ = [
    "NoValidLayoutError",
    "SobolStream",
    "sample_mixture",
    "first_valid",
    "Exploration",
    "explore",
    "exploration_parents",
]

logger = logging.getLogger(__name__)

SimulateFn = Callable[[np.ndarray], list[Label]]
ValidityFn = Callable[[np.ndarray], np.ndarray]
SubmitFn = Callable[[np.ndarray], Callable[[], Sequence[Label]]]

_MIN_LOG_STEP_SCALE = float(np.log(1 / 16))  # the exploration step's floor: 1/16 of the paper's


class NoValidLayoutError(RuntimeError):
    """Every layout the exploration's Sobol stage drew was invalid (``problem.validity``
    refused them all) and no start layout was given: nothing to simulate nor to draw around.
    ``n_drawn`` is how many it tested."""

    def __init__(self, n_drawn: int):
        self.n_drawn = n_drawn
        super().__init__(f"none of the {n_drawn} layouts the exploration drew is valid")


class SobolStream:
    """Consecutive blocks of one Sobol sequence in ``[0, 1]^d``.

    Blocks are drawn in powers of two so that the sequence keeps its balance properties.
    Unscrambled, the first point (the origin) is skipped, as sobol-seq did for the authors.

    Parameters
    ----------
    dimension : int
        d.
    scramble : bool
        Owen-scramble the sequence with ``rng`` (scipy's default and recommendation).
    rng : numpy.random.Generator
        Source of the scrambling.
    """

    def __init__(self, dimension: int, scramble: bool, rng: np.random.Generator):
        seed = int(rng.integers(2**63))
        try:
            self._engine = qmc.Sobol(dimension, scramble=scramble, rng=seed)
        except TypeError:  # scipy < 1.15
            self._engine = qmc.Sobol(dimension, scramble=scramble, seed=seed)
        self._skip_origin = not scramble
        self._buffer = np.empty((0, dimension))
        self.dimension = dimension

    def take(self, n: int) -> np.ndarray:
        """The next ``n`` points, (n, d)."""
        while len(self._buffer) < n:
            block = 2 ** int(np.ceil(np.log2(max(n - len(self._buffer) + 1, 2))))
            block = max(block, self._engine.num_generated, 2)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UserWarning)  # balance warning, see docstring
                points = self._engine.random(block)
            if self._skip_origin:
                points = points[1:]
                self._skip_origin = False
            self._buffer = np.vstack([self._buffer, points])
        out, self._buffer = self._buffer[:n], self._buffer[n:]
        return out

    def put_back(self, points: np.ndarray) -> None:
        """Return the last points taken, unused: the next :meth:`take` starts with them."""
        self._buffer = np.vstack([points, self._buffer])


def sample_mixture(
    means: np.ndarray,
    weights: np.ndarray,
    variances: np.ndarray | float,
    n: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """Draw from a mixture of axis-aligned Gaussians and clip to ``[0, 1]^d``.

    Parameters
    ----------
    means : (m, d) float
        Component means.
    weights : (m,) float
        Non-negative component weights (normalised here; must not all be 0).
    variances : float or (d,) or (m, d) float
        Diagonal covariances (**variances**, not standard deviations). A zero variance keeps
        that coordinate at the mean.
    n : int
        Number of samples.
    rng : numpy.random.Generator

    Returns
    -------
    (n, d) float
    """
    return _draw_mixture(means, weights, variances, n, rng)[0]


def _draw_mixture(means, weights, variances, n, rng) -> tuple[np.ndarray, np.ndarray]:
    """:func:`sample_mixture`, and the component each row was drawn from."""
    means = np.atleast_2d(np.asarray(means, dtype=float))
    m, d = means.shape
    w = np.asarray(weights, dtype=float)
    if w.shape != (m,) or np.any(w < 0) or not w.sum() > 0:
        raise ValueError("sample_mixture: weights must be (m,), non-negative, not all 0")
    var = np.broadcast_to(np.asarray(variances, dtype=float), (m, d))
    comps = rng.choice(m, size=n, p=w / w.sum())
    X = means[comps] + rng.standard_normal((n, d)) * np.sqrt(var[comps])
    return np.clip(X, 0.0, 1.0), comps


def first_valid(
    candidates: np.ndarray, validity: ValidityFn, n: int, chunk: int | None = None,
    rate: float = 1.0,
) -> tuple[np.ndarray, int]:
    """The first ``n`` valid rows of ``candidates``, testing them in order by blocks.

    Parameters
    ----------
    candidates : (m, d) float
    validity : callable
        ``validity(X) -> (k,) bool``.
    n : int
        Number of valid rows wanted.
    chunk : int, optional
        Fewest rows tested per call (default ``n``).
    rate : float
        Expected fraction of valid candidates. Each call tests enough rows to finish at that
        rate (the first) or at the rate observed so far (the next ones), with 20 % to spare:
        a call to a process pool costs milliseconds, a test a fraction of one. The rows
        returned do not depend on it; only how many are tested does.

    Returns
    -------
    valid_rows : (<= n, d) float
        Fewer than ``n`` rows if the candidates ran out.
    n_tested : int
        Number of candidates up to the last row returned (or all, when they ran out): the
        draws the valid rows cost, whatever extra rows a call tested.
    """
    chunk = max(1, int(chunk or n))
    kept: list[np.ndarray] = []
    n_kept = 0
    start = 0
    while n_kept < n and start < len(candidates):
        if start:
            rate = max(n_kept / start, 0.02)
        size = max(chunk if not start else 1, _block(n - n_kept, rate))
        block = candidates[start : start + size]
        ok = np.asarray(validity(block), dtype=bool)
        end = _through_nth_valid(ok, n - n_kept)  # rows tested past it do not count
        block, ok = block[:end], ok[:end]
        kept.append(block[ok])
        n_kept += int(ok.sum())
        start += len(block)
    out = np.vstack(kept) if kept else np.empty((0, candidates.shape[1]))
    return out, start


def _through_nth_valid(ok: np.ndarray, n: int) -> int:
    """Length of the prefix of ``ok`` that ends at its ``n``-th True (all of it if fewer)."""
    hits = np.flatnonzero(ok)
    return int(hits[n - 1]) + 1 if len(hits) >= n else len(ok)


def _block(needed: int, rate: float) -> int:
    """Rows to test to find ``needed`` valid ones at ``rate``, with 20 % to spare."""
    return needed if rate >= 1 else int(np.ceil(1.2 * needed / max(rate, 0.02)))


@dataclass(frozen=True)
class Exploration:
    """Result of :func:`explore`.

    Attributes
    ----------
    X : (n, d) float
        Simulated samples, in simulation order: the valid start layouts (if any), then the
        Sobol points, then the adaptive iterations' draws.
    labels : tuple of Label
        Their labels.
    n_iterations : int
        Adaptive iterations run after the Sobol batch.
    n_validity_tests : int
        Candidates drawn up to the last valid one used (see :func:`first_valid`).
    n_global_successes : int
        Samples that succeeded globally.
    keep_rates : tuple of float
        Per mixture batch, in simulation order: the fraction of its draws that succeeded in at
        least as many events as the sample each was drawn around.
    step_scales : tuple of float
        Per mixture batch: the factor on the paper's standard deviation it was drawn with
        (1.0 throughout with ``exploration_keep_rate`` = 0).
    stalled_at : int or None
        The iteration after which the exploration counted as stalled (its parents unchanged
        for ``exploration_stall_batches`` batches; later ties went to the newest), or None.
    """

    X: np.ndarray
    labels: tuple[Label, ...]
    n_iterations: int
    n_validity_tests: int
    n_global_successes: int
    keep_rates: tuple[float, ...] = ()
    step_scales: tuple[float, ...] = ()
    stalled_at: int | None = None


def explore(
    problem: Problem,
    settings: LearningSettings,
    rng: np.random.Generator,
    *,
    simulate: SimulateFn | None = None,
    submit: SubmitFn | None = None,
    starts: np.ndarray | None = None,
) -> Exploration:
    """Initial exploration by adaptive sampling (paper Alg. 1, authors'
    ``find_successful_samples_adaptive``).

    0. With ``starts`` (layouts the user already has), simulate the valid ones first: a start
       that succeeds, even partly, is then among the samples the mixtures grow around.
    1. Simulate the first ``n_initial`` valid points of a Sobol sequence (at most
       ``max_draws_factor * n_initial`` candidates).
    2. While fewer than ``n_successes`` samples succeeded globally and fewer than
       ``exploration_max_iter`` iterations ran: take the ``n_successes`` samples with the
       most successful events (oldest first on ties; once the exploration has stalled,
       newest first: step 4), build a mixture with one Gaussian per
       sample (weight proportional to its number of successful events, covariance
       ``exploration_variance * I``), and simulate its first ``exploration_batch`` valid
       draws (out of ``max_draws_factor`` times as many).
    3. With ``exploration_keep_rate`` = r > 0 (rgmcad's step control), the standard deviation
       of the components follows how often a batch's draws *keep* their progress (succeed
       in at least as many events as the sample they were drawn around): after a batch
       where a fraction p kept it, the step is multiplied by ``2 ** (p - r)``, never above
       the paper's step nor below 1/16 of it. Why: at the paper's fixed step (0.1 per
       coordinate, a jump of length 0.1 sqrt(d)) most draws in many dimensions undo events
       that already worked, and exploration stalls (docs/decisions.md, "Exploration step").
    4. With ``exploration_stall_batches`` = K > 0 (rgmcad's), once K mixture batches in a
       row left the parents unchanged (no draw beat the lowest count among them), ties at
       that count go to the newest samples for the rest of the exploration
       (:func:`exploration_parents`): the mixtures then follow their latest draws over the
       level they reached instead of circling the oldest samples there for good
       (docs/decisions.md, "Exploration stalls"). With ``exploration_stall_spacing`` > 0
       the parents taken then keep about a step apart (:func:`exploration_parents`).
    5. With ``exploration_move_share`` = p < 1 (off), each coordinate of a draw moves with
       probability p, one at least; the rest keep the parent's values (:mod:`.moves`).
    6. With ``exploration_staged`` = q > 0 and a problem that says which coordinates each
       event depends on (``event_dimensions``), a share q of the draws keep their parent's
       values on the coordinates of the events the parent achieved (:func:`.moves.staged`).

    When no selected sample has any successful event (the paper's weights would be 0/0),
    the iteration continues the Sobol sequence instead: with no partial success to grow
    from, space filling is the best guess.

    With ``settings.exploration_lag`` = L > 0 the iterations overlap: batch k is drawn from
    the results of the batches before k - L, so that L batches simulate while the next one
    is drawn and tested (see ``LearningSettings.exploration_lag``). The batches still in
    flight when the stop test passes are simulated and kept. The result depends on L, never
    on timing; L = 0 is the authors' sequential loop.

    Parameters
    ----------
    problem : Problem
    settings : LearningSettings
    rng : numpy.random.Generator
    simulate : callable, optional
        ``simulate(X) -> list[Label]``, default ``problem.simulate``; the driver passes one
        that records and parallelises.
    submit : callable, optional
        ``submit(X) -> wait`` starts simulating ``X`` and returns ``wait() -> list[Label]``;
        the batches are waited for in the order they were submitted. Default: ``simulate``,
        run when waited for.
    starts : (k, d) float in [0, 1]^d, optional
        Start layouts; invalid ones are left out. None: the paper's exploration, unchanged
        (no random draw depends on the starts).

    Returns
    -------
    Exploration
    """
    simulate = simulate or problem.simulate
    if submit is None:
        def submit(X):
            return lambda: simulate(X)
    s = settings
    d = problem.dimension
    event_dims = getattr(problem, "event_dimensions", None)
    sobol = SobolStream(d, s.sobol_scramble, rng)

    Xs, labels = [], []
    if starts is not None:
        starts = np.asarray(starts, dtype=float).reshape(-1, d)
        X_start = starts[np.asarray(problem.validity(starts), dtype=bool)] if len(starts) else starts
        if len(X_start) < len(starts):
            logger.warning("exploration: %d of %d start layouts are invalid, left out",
                           len(starts) - len(X_start), len(starts))
        if len(X_start):
            Xs.append(X_start)
            labels.extend(simulate(X_start))
    X0, n_tested = _sobol_valid(sobol, problem.validity, s.n_initial, s.max_draws_factor)
    if len(X0) == 0 and not labels:  # nothing valid to simulate, nor to draw around
        raise NoValidLayoutError(n_tested)
    if len(X0) < s.n_initial:
        logger.warning(
            "exploration: only %d valid Sobol points among %d candidates (wanted %d)",
            len(X0), n_tested, s.n_initial,
        )
    Xs.append(X0)
    labels.extend(simulate(X0) if len(X0) else [])
    n_succ = [lab.n_success for lab in labels]
    n_global = sum(lab.success for lab in labels)
    in_flight: deque[tuple[np.ndarray, np.ndarray | None, Callable[[], Sequence[Label]]]] = deque()
    k = 0
    drawing = True
    mixture_tested = mixture_valid = 0  # to size the validity calls (not the result)
    log_scale = 0.0  # log of the factor on the paper's standard deviation (step control)
    keep_rates: list[float] = []
    step_scales: list[float] = []
    unchanged, last_parents, stalled_at = 0, frozenset(), None  # stall detection
    while True:
        while in_flight and (len(in_flight) > s.exploration_lag or not drawing):
            Xk, parent_counts, wait = in_flight.popleft()
            new = list(wait())
            if parent_counts is not None:
                kept = float(np.mean([lab.n_success >= c
                                      for lab, c in zip(new, parent_counts, strict=True)]))
                keep_rates.append(kept)
                if s.exploration_keep_rate > 0:
                    change = np.log(2.0) * (kept - s.exploration_keep_rate)
                    log_scale = float(np.clip(log_scale + change, _MIN_LOG_STEP_SCALE, 0.0))
            Xs.append(Xk)
            labels.extend(new)
            n_succ.extend(lab.n_success for lab in new)
            n_global += sum(lab.success for lab in new)
            logger.debug("exploration: %d samples, %d global successes", len(labels), n_global)
        if not drawing:
            break
        if n_global >= s.n_successes or k >= s.exploration_max_iter:
            drawing = False  # wait for the batches in flight, then stop
            continue
        counts = np.asarray(n_succ, dtype=float)
        X_all = np.vstack(Xs)
        scale = float(np.exp(log_scale))
        spacing = (s.exploration_stall_spacing * np.sqrt(s.exploration_variance * d) * scale
                   if stalled_at is not None else 0.0)
        top = exploration_parents(counts, s.n_successes, newest_first=stalled_at is not None,
                                  X=X_all, spacing=spacing)
        w = counts[top]
        parent_counts = None
        if w.sum() > 0:
            parents = frozenset(top.tolist())
            unchanged = unchanged + 1 if parents == last_parents else 0
            last_parents = parents
            if stalled_at is None and 0 < s.exploration_stall_batches <= unchanged:
                stalled_at = k  # from the next batch on: newest first
                logger.info("exploration stalled at iteration %d: its parents did not change "
                            "for %d batches", k, unchanged)
            cands, comps = _draw_mixture(
                X_all[top], w, s.exploration_variance * scale**2,
                s.max_draws_factor * s.exploration_batch, rng,
            )
            if s.exploration_move_share < 1:
                cands = few_moved(cands, X_all[top][comps], s.exploration_move_share, rng)
            if s.exploration_staged > 0 and event_dims is not None:
                free = np.stack([free_coordinates(labels[i].events, event_dims, d) for i in top])
                cands = staged(cands, X_all[top][comps], free[comps], s.exploration_staged, rng,
                               event_masks(event_dims, d))
            rate = mixture_valid / mixture_tested if mixture_tested else 1.0
            # the component index rides along as a last column, unseen by the validity test
            tagged, nt = first_valid(np.column_stack([cands, comps]),
                                     lambda B: problem.validity(np.ascontiguousarray(B[:, :-1])),
                                     s.exploration_batch, rate=rate)
            Xk = np.ascontiguousarray(tagged[:, :-1])
            parent_counts = w[tagged[:, -1].astype(int)]
            step_scales.append(scale)
            mixture_tested += nt
            mixture_valid += len(Xk)
        else:
            Xk, nt = _sobol_valid(sobol, problem.validity, s.exploration_batch, s.max_draws_factor)
        n_tested += nt
        k += 1
        if len(Xk) == 0:
            logger.warning("exploration iteration %d: no valid candidate", k)
            continue
        in_flight.append((Xk, parent_counts, submit(Xk)))
    X = stack_rows(Xs, d)
    if n_global < s.n_successes:
        logger.info(
            "exploration stopped after %d iterations with %d/%d global successes",
            k, n_global, s.n_successes,
        )
    return Exploration(X, tuple(labels), k, n_tested, int(n_global), tuple(keep_rates),
                       tuple(step_scales), stalled_at)


def _sobol_valid(
    sobol: SobolStream, validity: ValidityFn, n: int, max_draws_factor: int
) -> tuple[np.ndarray, int]:
    """The next ``n`` valid Sobol points, drawing at most ``max_draws_factor * n``; the
    points tested beyond the ``n``-th valid one go back to the stream."""
    rows: list[np.ndarray] = []
    n_kept = n_tested = 0
    rate = 1.0
    while n_kept < n and n_tested < max_draws_factor * n:
        block = sobol.take(min(_block(n - n_kept, rate), max_draws_factor * n - n_tested))
        ok = np.asarray(validity(block), dtype=bool)
        end = _through_nth_valid(ok, n - n_kept)
        sobol.put_back(block[end:])
        block, ok = block[:end], ok[:end]
        rows.append(block[ok])
        n_kept += int(ok.sum())
        n_tested += len(block)
        rate = max(n_kept / n_tested, 0.02)
    return stack_rows(rows, sobol.dimension), n_tested


def stack_rows(rows: Sequence[np.ndarray], d: int) -> np.ndarray:
    """Stack a possibly empty list of (k, d) arrays."""
    return np.vstack(rows) if len(rows) else np.empty((0, d))
