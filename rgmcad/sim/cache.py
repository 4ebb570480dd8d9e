"""Data derived from built parts, computed once by whoever owns a :class:`PartCache`.

A simulation needs, per built part, things that cost more than the simulation's share of
them: the OBJ files of its convex pieces (pybullet compounds read files), its mass
properties, its mesh as a manifold3d solid (validity) and its convex hull's face equations
(inclusion events). They depend only on the part, so a caller that simulates many layouts
of one scenario (a worker process: :class:`~rgmcad.runs.problem.ScenarioContext`) keeps one
cache for all of them; a single simulation given none uses a fresh one. The results never
depend on what a cache held before.
"""

from __future__ import annotations

import shutil
import tempfile
import weakref
from collections.abc import Callable, Hashable
from typing import TypeVar

T = TypeVar("T")


class PartCache:
    """Values computed once per kind and per owner objects (built bodies, pieces), and a
    folder for files pybullet must read, removed by :meth:`close` (or garbage collection).

    Owners are matched by identity and kept alive by the cache, so an entry can never be
    taken for another object's.
    """

    def __init__(self):
        self._values: dict[tuple, tuple[tuple, object]] = {}
        self._directory: str | None = None
        self._remove = None

    def get(self, kind: Hashable, owners: object | tuple, make: Callable[[], T]) -> T:
        """The value of ``kind`` for ``owners`` (one object or a tuple of them), made by
        ``make()`` the first time."""
        owners = owners if isinstance(owners, tuple) else (owners,)
        key = (kind, *map(id, owners))
        hit = self._values.get(key)
        if hit is not None and all(a is b for a, b in zip(hit[0], owners, strict=True)):
            return hit[1]
        value = make()
        self._values[key] = (owners, value)
        return value

    def directory(self) -> str:
        """A private folder for derived files, created on first use."""
        if self._directory is None:
            self._directory = tempfile.mkdtemp(prefix="rgmcad-pieces-")
            self._remove = weakref.finalize(self, shutil.rmtree, self._directory, True)
        return self._directory

    def close(self) -> None:
        """Forget every value and remove the folder."""
        self._values.clear()
        if self._remove is not None:
            self._remove()
        self._directory = self._remove = None
