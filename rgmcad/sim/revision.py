"""The physics revision: the date of the last change to what a simulation returns.

Every measurement file the documentation is made from (a benchmark's ``benchmark.json``, the
time step table, the built-by-hand figures) records the revision it was measured under, and
the results pages mark a figure measured under an earlier one (:mod:`rgmcad.reference.results`),
so a page never presents a figure of superseded physics as current. ``tests/test_physics_revision.py``
holds the shipped `solved` layouts' event times under this revision and fails when a change
moves them: then this date is moved to the day of the change, with the new times.
"""

PHYSICS_REVISION = "2026-12-08"
"""Goblet pieces half-way between chord and tangent (docs/decisions.md, 2026-12-08); before it,
2026-12-07: collision margins that are the part's and hinged readers on the step's pose."""
