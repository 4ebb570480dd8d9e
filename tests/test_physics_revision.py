"""Law: the physics revision (rgmcad.sim.revision) names the physics that results are measured
under. The shipped `solved` layouts' event times (one per event, in the scenario's order, to
the millisecond: every time is a whole number of 2 ms steps) are those of that revision; a
change to the simulation that moves any of them must move the revision's date too, so that
the results pages mark every figure measured before it (rgmcad.reference.results)."""

import pytest

from rgmcad.runs.problem import ScenarioContext
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.shipped import scenario_path
from rgmcad.sim.revision import PHYSICS_REVISION

REVISION = "2026-12-08"
TIMES = {
    "simple": ("success", [0.012, 0.266, 0.356, 0.356, 0.53]),
    "ballrun": ("success", [0.034, 0.61, 0.62, 0.61, 0.806, 0.97, 1.388, 1.916]),
    "branching": ("success", [0.168, 0.36, 0.378, 0.508, 0.524, 0.394, 0.408, 1.396]),
    "causality_switch": ("success", [
        0.218, 0.754, 0.988, 1.502, 1.51, 1.582, 0.706, 0.822, 0.934, 0.948, 1.634, 1.758, 1.968,
        1.968]),
    "long_chain": ("success", [
        0.02, 0.166, 0.358, 0.436, 0.944, 0.992, 1.032, 1.432, 1.458, 1.512, 1.688, 1.688, 2.076]),
    "teapot": ("success", [
        0.052, 0.624, 0.734, 0.84, 1.906, 3.018, 3.292, 3.396, 3.396, 4.596, 5.932, 6.002, 0.748,
        0.796, 0.858, 1.366, 1.434, 2.18, 2.37, 2.37, 2.78, 4.076, 4.242, 3.49]),
}
"""Under REVISION: outcome and event times in seconds (None: the event did not happen)."""


@pytest.mark.parametrize("name", list(TIMES))
def test_the_solved_layouts_happen_as_the_revision_says(name):
    context = ScenarioContext.load(scenario_path(name))
    try:
        run = context.simulate_values(
            values_from_mapping(context.scenario, context.scenario.layouts["solved"])
        )
    finally:
        context.close()
    seen = (run.outcome.value, [None if t is None else round(t, 3) for _, t in run.events.values()])
    assert PHYSICS_REVISION == REVISION and seen == TIMES[name], (
        f"{name}'s `solved` layout now gives {seen}, under revision {PHYSICS_REVISION} "
        f"(this test's times are {REVISION}'s). If the change to the simulation is meant: set "
        "PHYSICS_REVISION (rgmcad/sim/revision.py) and REVISION to today's date and TIMES to "
        "the new times; the results pages then mark what was measured before it."
    )
