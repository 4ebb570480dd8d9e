"""Event conditions, evaluated on a running :class:`~rgmcad.sim.world.World`.

Each factory takes an :class:`~rgmcad.scene.model.EventSpec` and a world (at t = 0, where it reads
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
* falling / rising with ``point`` or ``end``: the vertical velocity of that point of the body,
  ``v_com + omega x (p - p_com)``, so a lever pivoted at its centre of mass (whose centre
  never moves) "rises" at its +x end. ``end`` is the centre of one face of the body's bounding
  box in its part frame. pivoting and toppling take no point: the angular velocity and the
  attitude of a rigid body are the same at every one of its points.

Negation (``EventSpec.negate``): ``true`` negates the condition here; ``"always"`` leaves the
condition as it is, and the causal graph fails the event when it holds (:mod:`rgmcad.sim.causal`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.spatial import ConvexHull

from rgmcad.geometry import invert, matmul, point_in_frame, sin_cos_degrees
from rgmcad.scene.eventspec import ENDS, Negation
from rgmcad.scene.model import EventSpec
from rgmcad.sim.world import World

Condition = Callable[[], bool]


def contact(spec: EventSpec, world: World) -> Condition:
    return world.contact_reader(spec.objects["first"], spec.objects["second"],
                                spec.params["tolerance"])


def no_contact(spec: EventSpec, world: World) -> Condition:
    touching = contact(spec, world)
    return lambda: not touching()


def rolling_on(spec: EventSpec, world: World) -> Condition:
    touching = world.contact_reader(spec.objects["rolling"], spec.objects["support"],
                                    spec.params["tolerance"])
    velocity = world.velocity_reader(spec.objects["rolling"])
    w2 = spec.params["min_angvel"] ** 2

    def condition():
        x, y, z = velocity()[1]
        return x * x + y * y + z * z > w2 and touching()

    return condition


def pivoting(spec: EventSpec, world: World) -> Condition:
    velocity = world.velocity_reader(spec.objects["body"])
    w2 = spec.params["min_angvel"] ** 2

    def condition():
        x, y, z = velocity()[1]
        return x * x + y * y + z * z > w2

    return condition


def end_point(built, end: str) -> np.ndarray:
    """(3,) centre of the ``end`` face ("+x", "-y", ...) of a built body's bounding box, in
    its part frame."""
    if end not in ENDS:
        raise ValueError(f"unknown end {end!r}; allowed: {', '.join(ENDS)}")
    bbox = np.asarray(built.bbox, float)
    point = bbox.mean(axis=0)
    axis = "xyz".index(end[1])
    point[axis] = bbox[1 if end[0] == "+" else 0, axis]
    return point


def event_point(spec: EventSpec, world: World) -> np.ndarray | None:
    """The point (3,) of the event's body, in its part frame, that the spec names with
    ``point`` or ``end``; None for the centre of mass."""
    if spec.point is not None:
        return np.asarray(spec.point, float)
    if spec.end is None:
        return None
    body = spec.objects["body"]
    built = world.scene.bodies[body].built
    if built is None:
        raise ValueError(f"event {spec.name!r}: {body!r} is an infinite plane and has no ends")
    return end_point(built, spec.end)


def point_velocity_reader(world: World, body: str, point) -> Callable[[], tuple]:
    """A function returning the world velocity (vx, vy, vz) m/s of ``point`` (3,), a point
    fixed in the body's part frame: ``v_com + omega x (p - p_com)``."""
    velocity = world.velocity_reader(body)
    where = world.point_reader(body, point)
    com_in_part = invert(world.handles[body].com_to_part)[:3, 3]
    com = world.point_reader(body, com_in_part)

    def read():
        (vx, vy, vz), (wx, wy, wz) = velocity()
        (px, py, pz), (cx, cy, cz) = where(), com()
        rx, ry, rz = px - cx, py - cy, pz - cz
        return (vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx)

    return read


def _vertical_velocity(spec: EventSpec, world: World) -> Callable[[], float]:
    """The body's vertical velocity (m/s): of its centre of mass, or of the spec's point."""
    body = spec.objects["body"]
    point = event_point(spec, world)
    if point is None:
        velocity = world.velocity_reader(body)
        return lambda: velocity()[0][2]
    velocity = point_velocity_reader(world, body, point)
    return lambda: velocity()[2]


def falling(spec: EventSpec, world: World) -> Condition:
    vz, v = _vertical_velocity(spec, world), abs(spec.params["min_linvel"])
    return lambda: vz() < -v


def rising(spec: EventSpec, world: World) -> Condition:
    vz, v = _vertical_velocity(spec, world), abs(spec.params["min_linvel"])
    return lambda: vz() > v


def stopping(spec: EventSpec, world: World) -> Condition:
    velocity = world.velocity_reader(spec.objects["body"])
    v2, w2 = spec.params["max_linvel"] ** 2, spec.params["max_angvel"] ** 2

    def condition():
        (a, b, c), (x, y, z) = velocity()
        return a * a + b * b + c * c < v2 and x * x + y * y + z * z < w2

    return condition


def not_moving(spec: EventSpec, world: World) -> Condition:
    body = spec.objects["body"]
    tol = spec.params["position_tolerance"]
    cos_limit = float(sin_cos_degrees(spec.params["angle_tolerance"])[1])
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
    cos_limit = float(sin_cos_degrees(spec.params["angle"])[1])
    start = world.pose(body)
    up_in_body = start[2, :3].copy()  # world up, in the body frame
    cos_tilt = world.up_reader(body, up_in_body)
    return lambda: cos_tilt() <= cos_limit


def _hull_equations(built) -> tuple[np.ndarray, np.ndarray]:
    """Outward face normals (k, 3) and offsets (k,) of a built body's convex hull."""
    hull = ConvexHull(np.asarray(built.vertices, float))
    return hull.equations[:, :3].copy(), hull.equations[:, 3].copy()


def inclusion(spec: EventSpec, world: World) -> Condition:
    inside, container = spec.objects["inside"], spec.objects["container"]
    inner = world.scene.bodies[inside].built
    outer = world.scene.bodies[container].built
    normals, offsets = world.cache.get("hull", outer, lambda: _hull_equations(outer))
    centre = world.point_reader(inside, inner.centre_of_mass)
    (x0, y0, z0), (x1, y1, z1) = np.asarray(outer.bbox, float).tolist()
    if world.scene.bodies[container].static:  # plain floats, the box rules out most steps
        rows = invert(world.pose(container))[:3].tolist()

        def condition():
            x, y, z = centre()
            point = [r[0] * x + r[1] * y + r[2] * z + r[3] for r in rows]
            if not (x0 <= point[0] <= x1 and y0 <= point[1] <= y1 and z0 <= point[2] <= z1):
                return False
            return bool((matmul(normals, point) + offsets).max() <= 0.0)

        return condition
    # A moving container: the centre in its centre-of-mass frame in plain floats, outside a box
    # holding the hull with a margin far above rounding errors is outside; else the exact test.
    frame = world.frame_reader(container)
    (k00, k01, k02, k03), (k10, k11, k12, k13), (k20, k21, k22, k23) = \
        invert(world.handles[container].com_to_part)[:3].tolist()
    hull_box = np.vstack([outer.bbox, np.asarray(outer.vertices, float)])
    (a0, b0, c0), (a1, b1, c1) = (hull_box.min(axis=0) - 1e-9).tolist(), \
        (hull_box.max(axis=0) + 1e-9).tolist()

    def condition():
        c = centre()
        position, quaternion = frame()
        u, v, w = point_in_frame(position, quaternion, c)
        if not (a0 <= k00 * u + k01 * v + k02 * w + k03 <= a1
                and b0 <= k10 * u + k11 * v + k12 * w + k13 <= b1
                and c0 <= k20 * u + k21 * v + k22 * w + k23 <= c1):
            return False
        to_local = invert(world.pose(container))
        local = matmul(to_local[:3, :3], c) + to_local[:3, 3]
        return bool((matmul(normals, local) + offsets).max() <= 0.0)

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
    """The condition of one event, negated for ``negate = true``.

    With ``negate = "always"`` it is the plain condition: the causal graph fails the event
    when it holds and succeeds it at the timeout (:class:`~rgmcad.sim.causal.CausalGraph`).
    """
    try:
        factory = EVENTS[spec.type]
    except KeyError:
        raise ValueError(f"unknown event type {spec.type!r}; allowed: {', '.join(EVENTS)}") from None
    condition = factory(spec, world)
    if spec.negate is Negation.ONCE:
        return lambda: not condition()
    return condition
