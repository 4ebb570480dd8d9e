"""Supports that stay clear of every moving body: designed from the paths of the nominal
run and of runs under a hand's placement errors and physical errors, then checked by
simulating those runs again with the stands as static bodies.

:func:`plan_supports` records, at every physics step of each run, where each moving body's
surface is (points about 2 mm apart), blocks the cells of each raised part's site those
points stand over (:class:`~rgmcad.making.placement.Site`), chooses the stands, and then
simulates every run again with the stands built into the world. A stand is *touched* when
the engine holds a contact point between it and a body closer than :data:`TOUCH` (1 mm); a
touched stand's site is blocked where it was touched and its stands chosen again, up to
``rounds`` times. Each run's outcome with the stands is compared with its
outcome without them. A stand follows its part: under a hand's errors it moves with it.

The runs are draw 0, 1, ... of :class:`~rgmcad.scene.perturbation.PhysicsDraw` under a seed
(common random numbers, as :mod:`rgmcad.runs.hand` measures), after the nominal run.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from rgmcad.geometry import invert, matmul
from rgmcad.making.beside import side_sites
from rgmcad.making.placement import PlacementSettings, Site, make_site, surface_samples
from rgmcad.making.stands import Stand
from rgmcad.making.supports import Holding, base_planes, holdings
from rgmcad.parts.store import BuiltPart
from rgmcad.runs.hand import DEFAULT_HAND, Hand
from rgmcad.scene.bodies import make_scene
from rgmcad.scene.model import Scenario
from rgmcad.scene.perturbation import DEFAULT_PHYSICS, PhysicsDraw, PhysicsRanges
from rgmcad.sim.cache import PartCache
from rgmcad.sim.engine import Engine, pb
from rgmcad.sim.run import simulate

__all__ = ["ClearanceSettings", "RunCheck", "SupportPlan", "plan_supports", "check_stands",
           "draws"]


TOUCH = 0.001
"""m: a body this close to a stand touches it (the engine reports contact points out to its
contact threshold, 2 mm; :attr:`RunCheck.closest` says how close the nearest came)."""


@dataclass(frozen=True)
class ClearanceSettings:
    """runs : perturbed runs besides the nominal one. seed : their draws' seed. hand,
    physics : the errors they draw (physics None: the scenario's). rounds : redesigns after
    a touch. placement : how stands are placed."""

    runs: int = 50
    seed: int = 0
    hand: Hand = DEFAULT_HAND
    physics: PhysicsRanges | None = DEFAULT_PHYSICS
    rounds: int = 3
    placement: PlacementSettings = field(default_factory=PlacementSettings)


def draws(settings: ClearanceSettings) -> list[PhysicsDraw | None]:
    """The nominal run (None) then the perturbed runs' draws."""
    ranges = settings.hand.ranges(settings.physics)
    return [None] + [PhysicsDraw(ranges, settings.seed, i) for i in range(settings.runs)]


@dataclass(frozen=True)
class RunCheck:
    """One run simulated without and with the stands: ``draw`` (-1: nominal), the outcomes
    and event states of each, the stands touched (label, body, time s) and the nearest a
    body came to a stand (m; inf: never within the engine's contact threshold)."""

    draw: int
    without: tuple
    with_stands: tuple
    touches: tuple[tuple[str, str, float], ...]
    closest: float = float("inf")

    @property
    def same(self) -> bool:
        return self.without == self.with_stands


@dataclass(frozen=True)
class SupportPlan:
    """The supports of one layout: every static part's holding, the stands, the raised
    parts left without one (name, why), and the last round of run checks."""

    holdings: tuple[Holding, ...]
    stands: tuple[Stand, ...]
    unsupported: tuple[tuple[str, str], ...]
    checks: tuple[RunCheck, ...]
    rounds: int

    @property
    def raised(self) -> list[Holding]:
        return [h for h in self.holdings if h.raised]

    @property
    def touched(self) -> list[RunCheck]:
        return [c for c in self.checks if c.touches]

    @property
    def changed(self) -> list[RunCheck]:
        return [c for c in self.checks if not c.same]

    def to_json(self) -> dict:
        """JSON-ready: the stands (:meth:`~rgmcad.making.stands.Stand.to_json`), the parts
        and what holds each, the parts left without a stand and the run checks' counts."""
        return {"stands": [s.to_json() for s in self.stands],
                "parts": [{"name": h.part.name, "held_by": h.held_by or None,
                           "base": h.base.name, "gap_mm": round(h.gap * 1000, 1)}
                          for h in self.holdings],
                "unsupported": [{"part": p, "why": why} for p, why in self.unsupported],
                "runs": len(self.checks), "runs_touched": len(self.touched),
                "runs_changed": len(self.changed), "rounds": self.rounds,
                "closest_mm": _mm(min((c.closest for c in self.checks), default=math.inf))}

    def summary(self) -> str:
        n = len(self.checks)
        return (f"{len(self.raised)} raised static parts, {len(self.stands)} stands, "
                f"{len(self.unsupported)} without a stand; {n} runs: "
                f"{n - len(self.touched)} with no stand touched, "
                f"{n - len(self.changed)} with the same outcome")


def _mm(metres: float) -> float | None:
    """Millimetres to 0.1, None for infinity (JSON has none)."""
    return None if math.isinf(metres) else round(metres * 1000, 1)


class _Recorder:
    """A step hook keeping every moving body's centre-of-mass frame at every step."""

    def __init__(self):
        self.frames: dict[str, list] = {}
        self.readers = None
        self.scene = None

    def __call__(self, world, t):
        if self.readers is None:
            self.scene = world.scene
            self.readers = {name: world.frame_reader(name) for name, b in world.scene.bodies.items()
                            if not b.static and name in world.handles}
            self.com = {name: world.handles[name].com_to_part for name in self.readers}
        for name, read in self.readers.items():
            self.frames.setdefault(name, []).append(read())

    def block(self, sites: Sequence[Site]) -> None:
        """Block the sites' cells under every recorded surface point."""
        if self.scene is None:
            return
        boxes = [_site_box(s) for s in sites]
        for name, frames in self.frames.items():
            built = self.scene.bodies[name].built
            pos = np.array([f[0] for f in frames])
            kept = _near_frames(frames, pos, boxes, built)
            if not kept:
                continue
            poses = _matrices(kept) @ self.com[name]
            chunks = _chunks(built)
            for site in sites:
                part = self.scene.bodies[site.holding.part.bodies[0]].pose
                local = site.to_local(part) @ poses  # the body in the site's frame
                lo, hi = site.bounds()
                for samples, centre, radius in chunks:
                    c = local[:, :3, :3] @ centre + local[:, :3, 3]
                    near = np.all((c >= lo - radius) & (c <= hi + radius), axis=1)
                    if not near.any():
                        continue
                    m = local[near]
                    pts = np.einsum("tij,nj->tni", m[:, :3, :3], samples) + m[:, None, :3, 3]
                    site.block_local(pts.reshape(-1, 3))


_CHUNKS: dict[int, tuple] = {}


def _chunks(built, size: float = 0.02) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """A body's surface samples in groups of ``size`` m cubes: [(samples (n, 3), centre
    (3,), radius m)], in its part frame; cached per body."""
    key = id(built)
    if key not in _CHUNKS or _CHUNKS[key][0] is not built:
        pts = surface_samples(built.vertices, built.faces)
        cells = np.floor(pts / size).astype(np.int64)
        _, inverse = np.unique(cells, axis=0, return_inverse=True)
        out = []
        for k in range(int(inverse.max()) + 1):
            group = pts[inverse.ravel() == k]
            centre = group.mean(0)
            out.append((group, centre, float(np.linalg.norm(group - centre, axis=1).max())))
        _CHUNKS[key] = (built, out)
    return _CHUNKS[key][1]


def _matrices(frames) -> np.ndarray:
    """(t, 4, 4) transforms of pybullet (position, (x, y, z, w) quaternion) pairs."""
    p = np.array([f[0] for f in frames], float)
    x, y, z, w = np.array([f[1] for f in frames], float).T
    m = np.zeros((len(p), 4, 4))
    m[:, 0] = np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w), p[:, 0]])
    m[:, 1] = np.column_stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w), p[:, 1]])
    m[:, 2] = np.column_stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y), p[:, 2]])
    m[:, 3, 3] = 1.0
    return m


def _site_box(site: Site):
    corners = np.array([[site.origin[0], site.origin[1]],
                        site.origin + site.settings.cell * np.array(site.blocked.shape)])
    a, b, c = site.top
    w = max(float(a * u + b * v + c) for u in corners[:, 0] for v in corners[:, 1])
    local = np.array([[u, v, z] for u in corners[:, 0] for v in corners[:, 1] for z in (0, w)])
    world = local @ site.frame[:3, :3].T + site.frame[:3, 3]
    return world.min(0), world.max(0)


def _near_frames(frames, pos, boxes, built, step: float = 0.002):
    """The frames whose body may reach into one of the boxes (a sphere test), skipping
    those where no point of the body moved ``step`` m since the last one kept."""
    radius = float(np.linalg.norm(np.asarray(built.bbox, float), axis=1).max()) + 0.01
    keep = np.zeros(len(frames), bool)
    for lo, hi in boxes:
        keep |= np.all((pos >= lo - radius) & (pos <= hi + radius), axis=1)
    out, last = [], None
    for i in np.nonzero(keep)[0]:
        p, q = frames[i]
        if last is not None:
            turn = 2.0 * np.arccos(min(abs(float(np.dot(q, last[1]))), 1.0))
            if np.linalg.norm(np.subtract(p, last[0])) + turn * radius < step:
                continue
        out.append(frames[i])
        last = (p, q)
    if keep.any() and out[-1] is not frames[np.nonzero(keep)[0][-1]]:
        out.append(frames[np.nonzero(keep)[0][-1]])
    return out


class _Stands:
    """A step hook that builds the stands as static bodies before the first step (each
    moved with its part) and then records every contact point the engine holds on them."""

    def __init__(self, stands: Sequence[Stand], nominal_poses: Mapping[str, np.ndarray],
                 part_body: Mapping[str, str]):
        self.stands, self.nominal, self.part_body = stands, nominal_poses, part_body
        self.uids = None
        self.touches: list[tuple[str, str, float, np.ndarray]] = []
        self.touch, self.closest = TOUCH, float("inf")

    def __call__(self, world, t):
        if self.uids is None:
            self._build(world)
        cid = world.cid
        for label, uid in self.uids:
            for c in pb.getContactPoints(bodyA=uid, physicsClientId=cid):
                self.closest = min(self.closest, c[8])
                if c[8] <= self.touch:
                    other = self.names.get((c[2], c[4]), f"body {c[2]}")
                    self.touches.append((label, other, t, np.asarray(c[6], float)))

    def _build(self, world):
        e = world.engine
        self.uids = []
        for stand in self.stands:
            body = self.part_body[stand.part]
            moved = stand.moved(matmul(world.scene.bodies[body].pose,
                                       invert(self.nominal[stand.part])))
            shape = e.createCollisionShape(pb.GEOM_MESH, vertices=moved.vertices().tolist())
            uid = e.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape,
                                    useMaximalCoordinates=True)
            e.changeDynamics(uid, -1, collisionMargin=world.settings.convex_margin)
            self.uids.append((stand.label, uid))
        self.names = {(h.uid, h.link): name for name, h in world.handles.items()}


def _states(result) -> tuple:
    return (result.outcome.value, tuple(e.state.value for e in result.events))


def _run(scenario, values, parts, draw, hooks, engine, cache):
    return simulate(scenario, values, parts, hooks=tuple(hooks), physics=draw,
                    engine=engine, cache=cache)


def check_stands(scenario: Scenario, values, parts: Mapping[str, BuiltPart],
                 stands: Sequence[Stand], run_draws: Sequence[PhysicsDraw | None],
                 baseline: Sequence[tuple] | None = None, engine: Engine | None = None,
                 cache: PartCache | None = None) -> tuple[list[RunCheck], list]:
    """Simulate each draw with the stands (and without them, unless ``baseline`` gives
    those outcomes): the run checks, and every touch (label, body, t, (3,) world point)."""
    values = np.asarray(values, float)
    scene = make_scene(scenario, values, parts)
    part_body = {h.part.name: h.part.bodies[0] for h in holdings(scene)}
    nominal = {name: scene.bodies[b].pose for name, b in part_body.items()}
    own = engine is None
    engine = Engine(renderer=False) if own else engine
    cache = PartCache() if cache is None else cache
    checks, touches = [], []
    try:
        for k, draw in enumerate(run_draws):
            before = baseline[k] if baseline is not None else _states(
                _run(scenario, values, parts, draw, (), engine, cache))
            hook = _Stands(stands, nominal, part_body)
            after = _states(_run(scenario, values, parts, draw, (hook,), engine, cache))
            checks.append(RunCheck(-1 if draw is None else draw.index, before, after,
                                   tuple(sorted({(a, b, round(t, 3)) for a, b, t, _ in
                                                 hook.touches}))[:20], hook.closest))
            touches += [(a, b, t, p, draw) for a, b, t, p in hook.touches]
    finally:
        if own:
            engine.close()
    return checks, touches


def plan_supports(scenario: Scenario, values, parts: Mapping[str, BuiltPart],
                  settings: ClearanceSettings = ClearanceSettings()) -> SupportPlan:
    """Stands for every raised static part of the layout ``values`` (d,), clear of the
    moving bodies of the nominal run and ``settings.runs`` perturbed runs (see the module)."""
    values = np.asarray(values, float)
    scene = make_scene(scenario, values, parts)
    planes = base_planes(scene)
    held = holdings(scene, planes)
    bases = {h.fixed for h in scene.hinges if h.fixed is not None}
    groups = [_sites(scene, h, planes, settings.placement, bool(bases & set(h.part.bodies)))
              for h in held if h.raised]
    run_draws = draws(settings)
    engine, cache = Engine(renderer=False), PartCache()
    try:
        baseline = []
        for draw in run_draws:
            recorder = _Recorder()
            baseline.append(_states(_run(scenario, values, parts, draw, (recorder,),
                                         engine, cache)))
            recorder.block([site for group in groups for site in group])
        by_site, made_by = _choose_all(groups)
        # a redesign is checked on the runs that touched first, then on every run
        everyone = list(range(len(run_draws)))
        pending, checked, rounds = everyone, {}, 1
        while True:
            stands = [s for group in by_site for s in group]
            new, touches = check_stands(scenario, values, parts, stands,
                                        [run_draws[k] for k in pending],
                                        [baseline[k] for k in pending], engine, cache)
            checked.update(zip(pending, new, strict=True))
            if not touches or rounds > settings.rounds:
                if pending == everyone:
                    break
                pending = everyone  # the last stands, on every run
                continue
            for label, _, _, point, draw in touches:
                site = made_by[label]
                part_pose = _part_pose(scenario, values, parts, site, draw, engine, cache)
                site.block(point[None], part_pose)
            by_site, made_by = _choose_all(groups)
            rounds += 1
            pending = [k for k, c in zip(pending, new, strict=True) if c.touches]
        checks = [checked[k] for k in everyone]
    finally:
        engine.close()
        cache.close()
    stands = tuple(s for group in by_site for s in group)
    unsupported = tuple((group[0].name, "no clear room for a stand under it"
                         + (" nor for a post beside it"
                            if any(s.face_u is not None for s in group) else ""))
                        for group, stands in zip(groups, by_site, strict=True) if not stands)
    return SupportPlan(tuple(held), stands, unsupported, tuple(checks), rounds)


AXLE_SIZES_MM = ((6.0, 4.0), (4.0, 4.0))
"""Spacers smaller than any stand, tried last under a hinged part's fixed base (a lever's
axle, 4 mm thick: a spacer the size of its end)."""


def _sites(scene, holding: Holding, planes, placement: PlacementSettings,
           hinged: bool) -> list[Site]:
    """Where a raised part's stands may go, in the order tried: under it on its base (a
    shelf, or a plane), under it on the nearest plane when its base is a shelf, then, for
    a hinged part's base, posts beside its ends on each of those."""
    bases = [holding]
    if holding.base.outline is not None:  # a shelf: the plane below it is a base too
        pts = np.concatenate([scene.bodies[n].world_vertices() for n in holding.part.bodies])
        gaps = [(plane.gap(pts), plane) for plane in planes]
        gap, plane = min([(g, p) for g, p in gaps if g > 0] or gaps, key=lambda gp: gp[0])
        bases.append(Holding(holding.part, holding.held_by, gap, plane))
    if hinged:
        placement = dataclasses.replace(placement,
                                        sizes_mm=placement.sizes_mm + AXLE_SIZES_MM)
    out = [make_site(scene, h, placement) for h in bases]
    if hinged:
        out += [site for h in bases for site in side_sites(scene, h)]
    return out


def _choose_all(groups: Sequence[Sequence[Site]]) -> tuple[list[list[Stand]], dict]:
    """Each part's stands (from its first site that has room: under it, else beside it)
    and the site that made each stand, by label."""
    out, made_by, n = [], {}, 1
    for group in groups:
        stands = []
        for site in group:
            stands = site.choose(n)
            if stands:
                made_by.update((s.label, site) for s in stands)
                break
        out.append(stands)
        n += len(stands)
    return out, made_by


def _part_pose(scenario, values, parts, site: Site, draw, engine, cache) -> np.ndarray:
    """The pose of the site's part in the run of ``draw`` (as placed by its hand)."""
    if draw is None or not draw.ranges.moves_parts:
        return site.part_pose
    seen = {}

    def hook(world, t):
        if not seen:
            seen["pose"] = world.scene.bodies[site.holding.part.bodies[0]].pose

    short = dataclasses.replace(scenario, settings=dataclasses.replace(
        scenario.settings, duration=scenario.settings.timestep))
    _run(short, values, parts, draw, (hook,), engine, cache)
    return seen.get("pose", site.part_pose)
