"""Event conditions, evaluated on a running :class:`~rgmcad.physics.World`.

Each factory takes an :class:`~rgmcad.scenario.EventSpec` and a world (at t = 0, where it reads
any initial state it needs) and returns a condition: a function of no arguments, true when the
event's condition holds now. Conditions run before every physics step while their event is
awake, so they are closures over pre-resolved handles and use plain floats, not numpy.

Semantics and where they depart from the paper's code (SPEC.md 2.1):

* contact / no_contact / rolling_on: the bodies' closest distance is at most ``tolerance``
  (1 mm by default). The paper's engine reported a sphere as touching a box up to about one
  radius away, so its "ball hits X" fired early by a size-dependent margin; ours is a gap in
  metres that a user can reason about.
* toppling: the angle between the body's initial vertical direction and its current one
  reaches ``angle`` degrees. The paper read the roll angle relative to the parent frame and
  added 1 degree; tilt does not depend on frames or on spin about the vertical.
* not_moving: the part frame is within ``position_tolerance`` metres of its start and has
  turned by at most ``angle_tolerance`` degrees (one rotation angle instead of three Euler
  angle differences, which jump at +-180).
* inclusion: the centre of mass of ``inside`` lies in the convex hull of ``container``'s
  mesh. The paper cast rays of a bounding-sphere radius; the hull test is exact for cups and
  boxes, cheap, and has no ray-length tuning.
* pivoting, falling, rising, stopping: as in the paper (speeds of the body's centre of mass).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull

from rgmcad.physics import World
from rgmcad.scenario import EventSpec

Condition = Callable[[], bool]


def _norm(v) -> float:
    return math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])


def contact(spec: EventSpec, world: World) -> Condition:
    a, b, tol = spec.objects["first"], spec.objects["second"], spec.params["tolerance"]
    return lambda: world.touching(a, b, tol)


def no_contact(spec: EventSpec, world: World) -> Condition:
    a, b, tol = spec.objects["first"], spec.objects["second"], spec.params["tolerance"]
    return lambda: not world.touching(a, b, tol)


def rolling_on(spec: EventSpec, world: World) -> Condition:
    a, b = spec.objects["rolling"], spec.objects["support"]
    tol, w = spec.params["tolerance"], spec.params["min_angvel"]

    def condition():
        return _norm(world.velocity(a)[1]) > w and world.touching(a, b, tol)

    return condition


def pivoting(spec: EventSpec, world: World) -> Condition:
    body, w = spec.objects["body"], spec.params["min_angvel"]
    return lambda: _norm(world.velocity(body)[1]) > w


def falling(spec: EventSpec, world: World) -> Condition:
    body, v = spec.objects["body"], abs(spec.params["min_linvel"])
    return lambda: world.velocity(body)[0][2] < -v


def rising(spec: EventSpec, world: World) -> Condition:
    body, v = spec.objects["body"], abs(spec.params["min_linvel"])
    return lambda: world.velocity(body)[0][2] > v


def stopping(spec: EventSpec, world: World) -> Condition:
    body = spec.objects["body"]
    v, w = spec.params["max_linvel"], spec.params["max_angvel"]

    def condition():
        lin, ang = world.velocity(body)
        return _norm(lin) < v and _norm(ang) < w

    return condition


def not_moving(spec: EventSpec, world: World) -> Condition:
    body = spec.objects["body"]
    tol = spec.params["position_tolerance"]
    cos_limit = math.cos(math.radians(spec.params["angle_tolerance"]))
    start = world.pose(body)

    def condition():
        now = world.pose(body)
        if np.abs(now[:3, 3] - start[:3, 3]).max() > tol:
            return False
        # rotation angle of start^T now: trace = 1 + 2 cos(angle)
        trace = float(np.sum(start[:3, :3] * now[:3, :3]))
        return (trace - 1) / 2 >= cos_limit

    return condition


def toppling(spec: EventSpec, world: World) -> Condition:
    body = spec.objects["body"]
    cos_limit = math.cos(math.radians(spec.params["angle"]))
    start = world.pose(body)
    up_in_body = start[:3, :3].T @ np.array([0.0, 0.0, 1.0])  # world up, in the body frame

    def condition():
        now = world.pose(body)
        return float(now[2, :3] @ up_in_body) <= cos_limit

    return condition


def inclusion(spec: EventSpec, world: World) -> Condition:
    inside, container = spec.objects["inside"], spec.objects["container"]
    inner = world.scene.bodies[inside].built
    outer = world.scene.bodies[container].built
    hull = ConvexHull(np.asarray(outer.vertices, float))
    normals, offsets = hull.equations[:, :3], hull.equations[:, 3]
    centre = np.append(np.asarray(inner.centre_of_mass, float), 1.0)

    def condition():
        point = (np.linalg.solve(world.pose(container), world.pose(inside) @ centre))[:3]
        return bool(np.all(normals @ point + offsets <= 0.0))

    return condition


EVENTS: dict[str, Callable[[EventSpec, World], Condition]] = {
    "contact": contact,
    "no_contact": no_contact,
    "rolling_on": rolling_on,
    "pivoting": pivoting,
    "falling": falling,
    "rising": rising,
    "stopping": stopping,
    "not_moving": not_moving,
    "toppling": toppling,
    "inclusion": inclusion,
}


def make_condition(spec: EventSpec, world: World) -> Condition:
    """The condition of one event, negated when the spec asks for it."""
    try:
        factory = EVENTS[spec.type]
    except KeyError:
        raise ValueError(f"unknown event type {spec.type!r}; allowed: {', '.join(EVENTS)}") from None
    condition = factory(spec, world)
    if spec.negate:
        return lambda: not condition()
    return condition
