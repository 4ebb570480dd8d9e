"""The event types a causal graph can use: their object roles and parameters (pure data).

The conditions themselves live in :mod:`rgmcad.events`; this table is what scenario files are
checked against, so a scenario can be validated without building any physics.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class EventType:
    name: str
    roles: tuple[str, ...]  # keys naming objects
    params: dict[str, float | None]  # threshold name -> default (None: required)
    doc: str


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
                  "the body moves down faster than min_linvel m/s"),
        EventType("rising", ("body",), {"min_linvel": 0.0},
                  "the body moves up faster than min_linvel m/s"),
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
