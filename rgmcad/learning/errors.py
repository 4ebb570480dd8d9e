"""The errors a layout should survive, as a fixed design of offsets in ``[0, 1]^d``.

Two kinds, chosen by :class:`~rgmcad.learning.settings.LearningSettings`:

* **Gaussian placement errors** (``error_radius = 0``): every coordinate off by a normal
  error of standard deviation ``placement_noise``; offsets that leave the cube are kept (the
  refinement) or clipped onto it (the verification), as before.
* **The errors of global robustness** (``error_radius = R > 0``): a radius uniform in
  ``[0, R]``, then a point uniform in the Euclidean ball of that radius intersected with the
  cube (sampled by mirroring, see :meth:`ErrorDesign.at`). With ``R = 1`` the expected
  success under these errors *is* ``rho_g`` (the integral of ``rho_l(eps)`` over ``eps`` in
  ``[0, 1]``, :mod:`rgmcad.runs.robustness`), the figure the paper and the benchmark judge
  layouts by. The design is stratified in ``levels`` radii; a layout's expectation
  averages each radius's ball, then the radii, as ``rho_l`` conditions each ball on the cube.

Designs are deterministic (unscrambled Sobol points), so an objective built on one is a
smooth, deterministic function of ``x``, and two layouts scored with one design meet the same
errors (common random numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri
from scipy.stats import qmc

__all__ = ["ErrorDesign", "gaussian_errors", "ball_errors", "design_from_settings",
           "expected_success", "mirrored_offsets"]


@dataclass(frozen=True)
class ErrorDesign:
    """Offsets ``(k, d)`` and, for ball errors, the radius level of each ``(k,)``.

    ``levels`` is None for Gaussian errors: every offset counts alike and none is moved.
    """

    offsets: np.ndarray
    levels: np.ndarray | None = None

    @property
    def within_cube(self) -> bool:
        """Whether the errors keep the layout in the cube (ball errors, by :meth:`at`)."""
        return self.levels is not None

    def at(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The errors around ``x`` (d,): offsets ``(k, d)`` and raw weights ``(k,)``.

        Gaussian designs: the offsets, equal weights. Ball designs sample the ball
        *intersected with the cube*; near a face, rejecting the offsets that leave it would
        leave few (at a corner of an 8-D cube, 1 in 256), so each coordinate that leaves
        the cube is mirrored back (``-o_j``), and importance weights undo the bias: a
        coordinate ``t`` is reached both by itself and, when ``x_j - t`` is outside, by its
        mirror, so it weighs 1/2 there (the ball is symmetric in every coordinate's sign).
        Offsets still outside (past both faces) weigh 0. Use :meth:`normalized` to turn
        raw weights into the estimator's.
        """
        k = len(self.offsets)
        if self.levels is None:
            return self.offsets, np.ones(k)
        x = np.asarray(x, dtype=float).reshape(1, -1)
        F = mirrored_offsets(x, self.offsets)
        inside = np.all((x + F >= 0.0) & (x + F <= 1.0), axis=1)
        mirror_out = (x - F < 0.0) | (x - F > 1.0)
        return F, inside * 0.5 ** mirror_out.sum(axis=1)

    def interleaved(self) -> ErrorDesign:
        """The same offsets reordered so that every prefix whose length is a multiple of the
        number of levels holds as many offsets of each level, each level's in its own order
        (ball designs store their levels as consecutive blocks). A Gaussian design is
        returned as it is: its Sobol order already spreads every power-of-two prefix."""
        if self.levels is None:
            return self
        position = np.arange(len(self.levels)) - np.searchsorted(self.levels, self.levels)
        order = np.lexsort((self.levels, position))
        return ErrorDesign(self.offsets[order], self.levels[order])

    def head(self, k: int) -> ErrorDesign:
        """The first ``k`` errors."""
        return ErrorDesign(self.offsets[:k], None if self.levels is None else self.levels[:k])

    def then(self, other: ErrorDesign) -> ErrorDesign:
        """This design's errors followed by ``other``'s (of the same kind and dimension)."""
        levels = None if self.levels is None else np.concatenate([self.levels, other.levels])
        return ErrorDesign(np.vstack([self.offsets, other.offsets]), levels)

    def normalized(self, raw: np.ndarray) -> np.ndarray:
        """(k,) weights summing to 1 from raw ones (0 = left out): per radius level
        normalised, then the levels with any weight averaged (all 0 when none has)."""
        raw = np.asarray(raw, dtype=float)
        if self.levels is None:
            total = raw.sum()
            return raw / total if total > 0 else raw * 0.0
        sums = np.bincount(self.levels, weights=raw, minlength=int(self.levels.max()) + 1)
        used = sums > 0
        if not used.any():
            return np.zeros(len(raw))
        return np.where(raw > 0, raw / np.where(used, sums, 1.0)[self.levels], 0.0) / used.sum()


def mirrored_offsets(x: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """``offsets`` (k, d) with each coordinate that would take ``x`` out of ``[0, 1]``
    negated (mirrored back into the cube; one that leaves past both faces stays out)."""
    out = (x + offsets < 0.0) | (x + offsets > 1.0)
    return np.where(out, -offsets, offsets)


def _sobol_midpoints(dim: int, m: int, scramble: int | None = None) -> np.ndarray:
    """The first ``m`` unscrambled Sobol points in ``dim`` dimensions, moved to the middle of
    their strata (so none is 0, whose normal quantile is infinite); with ``scramble``, the
    points of the Sobol sequence scrambled with that seed instead (a design independent of
    the unscrambled one, as deterministic), kept off 0 and 1."""
    if scramble is None:
        return qmc.Sobol(dim, scramble=False).random(m) + 0.5 / m
    return np.clip(qmc.Sobol(dim, scramble=True, seed=scramble).random(m), 0.25 / m, 1 - 0.25 / m)


def _power_of_two(n: int) -> int:
    return 2 ** int(np.ceil(np.log2(max(n, 2))))


def gaussian_errors(d: int, sigma: float, n: int, scramble: int | None = None) -> ErrorDesign:
    """Gaussian errors of standard deviation ``sigma``: ``n`` rounded up to a power of two
    points of an unscrambled Sobol sequence, moved to the midpoints of their strata, through
    the normal quantile; each column is then a permutation of the stratified normal
    quantiles, rescaled to mean 0 and standard deviation exactly ``sigma``. ``scramble``: see
    :func:`_sobol_midpoints`."""
    z = ndtri(_sobol_midpoints(d, _power_of_two(n), scramble))
    return ErrorDesign(sigma * z / z.std(axis=0))


def ball_errors(d: int, radius: float, n: int, levels: int = 8,
                scramble: int | None = None) -> ErrorDesign:
    """The errors of global robustness up to ``radius`` (see the module docstring):
    ``n`` rounded up to a power of two offsets, ``levels`` radii ``radius * (l + 1/2) /
    levels``, each offset uniform in the ball of its level's radius. ``scramble``: see
    :func:`_sobol_midpoints`."""
    m = _power_of_two(max(n, levels))
    u = _sobol_midpoints(d + 1, m, scramble)
    directions = ndtri(u[:, 1:])
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    # consecutive blocks of Sobol points, each well spread (every 2^k-th point, as i % levels
    # would pick, shares leading digits: one block of radial fractions and directions)
    level = np.minimum(np.arange(m) * levels // m, levels - 1)
    eps = radius * (level + 0.5) / levels
    return ErrorDesign(directions * (eps * u[:, 0] ** (1.0 / d))[:, None], level)


def design_from_settings(d: int, settings, n: int, sigma: float,
                         scramble: int | None = None) -> ErrorDesign | None:
    """The design the settings ask for, with ``n`` offsets: ball errors up to
    ``settings.error_radius`` when it is positive, else Gaussian errors of ``sigma`` (None
    when ``sigma`` is 0: the point itself). ``scramble``: an independent design of the same
    errors (:func:`_sobol_midpoints`)."""
    if settings.error_radius > 0:
        return ball_errors(d, settings.error_radius, n, scramble=scramble)
    if sigma > 0:
        return gaussian_errors(d, sigma, n, scramble)
    return None


def expected_success(model, X: np.ndarray, design: ErrorDesign | None) -> np.ndarray:
    """(n,) the model's predicted success of each row of ``X`` (n, d) averaged over the
    design's errors (the point's own prediction where no offset stays in the cube)."""
    X = np.atleast_2d(np.asarray(X, dtype=float))
    if design is None:
        return model.success_proba(X)
    at = [design.at(x) for x in X]
    P = np.concatenate([x + offsets for x, (offsets, _) in zip(X, at, strict=True)])
    p = model.success_proba(P).reshape(len(X), -1)
    W = np.stack([design.normalized(raw) for _, raw in at])
    out = (p * W).sum(axis=1)
    empty = W.sum(axis=1) == 0
    if empty.any():
        out[empty] = model.success_proba(X[empty])
    return out
