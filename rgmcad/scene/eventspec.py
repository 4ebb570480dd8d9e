"""The event types a causal graph can use: their object roles and parameters (pure data).

The conditions themselves live in :mod:`rgmcad.sim.events`; this table is what scenario files are
checked against, so a scenario can be validated without building any physics.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


@dataclass(frozen=True)
class EventType:
    name: str
    roles: tuple[str, ...]  # keys naming objects
    params: dict[str, float | None]  # threshold name -> default (None: required)
    doc: str
    takes_point: bool = False  # accepts `point` or `end`: the body point whose motion counts


class Negation(Enum):
    """What ``negate`` asks of an event (see :mod:`rgmcad.sim.causal`).

    * ``OFF`` (``negate = false``): the condition holds (for ``hold`` s) before the timeout.
    * ``ONCE`` (``negate = true``): the condition is *false* (for ``hold`` s) at some time
      before the timeout; it may have held before and may hold again after.
    * ``ALWAYS`` (``negate = "always"``): the condition never holds (for ``hold`` s) from the
      moment the event wakes until its timeout; the event fails at the first step it does,
      and succeeds at the timeout.
    """

    OFF = False
    ONCE = True
    ALWAYS = "always"

    def __bool__(self) -> bool:
        return self is not Negation.OFF

    @property
    def label(self) -> str:
        """How a scenario file writes it: false, true or always."""
        return {Negation.OFF: "false", Negation.ONCE: "true"}.get(self, self.value)


NEGATE_VALUES = "true, false or \"always\""
"""The values ``negate`` accepts, as an error message lists them."""

ENDS = ("+x", "-x", "+y", "-y", "+z", "-z")
"""The values of an event's ``end``: the centre of that face of the body's bounding box."""

POINT_KEYS = ("x", "y", "z")


CONTACT_TOLERANCE = 1e-3
"""Default gap (m) at or below which two bodies count as touching (see events.py)."""

EVENT_TYPES: dict[str, EventType] = {
    e.name: e
    for e in [
        EventType("contact", ("first", "second"), {"tolerance": CONTACT_TOLERANCE},
                  "the two bodies touch (gap <= tolerance metres)"),
        EventType("no_contact", ("first", "second"), {"tolerance": CONTACT_TOLERANCE},
                  "the two bodies do not touch (gap > tolerance metres)"),
        EventType("rolling_on", ("rolling", "support"),
                  {"min_angvel": 0.0, "tolerance": CONTACT_TOLERANCE},
                  "`rolling` touches `support` and spins faster than min_angvel rad/s"),
        EventType("pivoting", ("body",), {"min_angvel": 0.0},
                  "the body turns faster than min_angvel rad/s"),
        EventType("falling", ("body",), {"min_linvel": 0.0},
                  "the body (its centre of mass, or its `point` / `end`) moves down faster "
                  "than min_linvel m/s", takes_point=True),
        EventType("rising", ("body",), {"min_linvel": 0.0},
                  "the body (its centre of mass, or its `point` / `end`) moves up faster "
                  "than min_linvel m/s", takes_point=True),
        EventType("stopping", ("body",), {"max_linvel": 1e-3, "max_angvel": 1.0},
                  "the body moves slower than max_linvel m/s and turns slower than max_angvel rad/s"),
        EventType("not_moving", ("body",), {"position_tolerance": 1e-3, "angle_tolerance": 1.0},
                  "the body is within position_tolerance m and angle_tolerance deg of its start"),
        EventType("toppling", ("body",), {"angle": None},
                  "the body has tilted by at least `angle` degrees from its starting attitude"),
        EventType("inclusion", ("inside", "container"), {},
                  "the centre of mass of `inside` lies within the convex hull of `container`"),
    ]
}
