"""A simulated run recorded for replay: every body's mesh, the poses of the moving ones at a
fixed rate, and the causal graph's events.

Poses are read through the simulation's ``observer`` hook (:func:`rgmcad.sim.run.simulate`),
so recording changes nothing in the run. The stored form (:func:`replay_payload`) is compact:
meshes shared between bodies are stored once (float32 vertices, uint16/uint32 triangles);
positions are quantised to int16 over the scene's bounding box (a step of its size / 65 534,
0.03 mm for a 2 m scene) and unit quaternions to int16 (a step of 3e-5); all arrays are
little-endian and base64 encoded.
"""

from __future__ import annotations

import base64
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from rgmcad.geometry import transform_points
from rgmcad.scene.model import Scenario
from rgmcad.scene.palette import plane_colour, runs_of, scene_colours

__all__ = ["DEFAULT_RATE", "Replay", "record_replay", "replay_payload", "scene_meshes"]

DEFAULT_RATE = 100.0
"""Poses recorded per simulated second."""

_Q = 32767  # int16 scale of a unit quaternion component and of a position in [-1, 1]


@dataclass(frozen=True, eq=False)
class Replay:
    """A recorded run.

    Attributes
    ----------
    title : str
    bodies : tuple of str
        Body names, scene order (infinite planes excluded).
    meshes : tuple of (vertices (n, 3) float, faces (m, 3) int)
        Distinct meshes, part frame, metres.
    mesh_of : (b,) int
        Each body's mesh.
    static : (b,) bool
        Bodies that never move.
    colors : (b, 3) float
        RGB in [0, 1].
    planes : tuple of (4, 4) float
        World transforms of infinite planes (their +z is the normal).
    times : (f,) float
        Seconds of every recorded frame.
    poses : (f, b, 4, 4) float
        World transform of every body's part frame at every frame.
    events : tuple of dict
        ``{"name", "after", "join", "state", "time", "description"}`` in the scenario's order.
    outcome : str
    labels : tuple of str, optional
        What names each body in the viewer's labels: its object, or its domino run (labelled
        once, at its first domino). None: read from the body's name.
    """

    title: str
    bodies: tuple[str, ...]
    meshes: tuple[tuple[np.ndarray, np.ndarray], ...]
    mesh_of: np.ndarray
    static: np.ndarray
    colors: np.ndarray
    planes: tuple[np.ndarray, ...]
    times: np.ndarray
    poses: np.ndarray
    events: tuple[dict, ...]
    outcome: str
    labels: tuple[str, ...] | None = None


def record_replay(scenario: Scenario, values, parts: Mapping, *, rate: float = DEFAULT_RATE,
                  title: str | None = None, **simulate_kwargs):
    """Simulate the layout with real parameter ``values`` (d,) and record it.

    Returns ``(result, replay)``: the :class:`~rgmcad.sim.run.SimulationResult` (exactly the
    one :func:`~rgmcad.sim.run.simulate` gives without recording) and a :class:`Replay`
    (None for an invalid layout, which is not simulated). ``rate``: frames per simulated
    second (at most one per physics step).
    """
    from rgmcad.sim.run import simulate

    if not rate > 0:
        raise ValueError(f"recording rate {rate!r}: expected a positive number of frames/s")
    every = max(1, int(round(1.0 / (rate * scenario.settings.timestep))))
    frames: list[np.ndarray] = []
    times: list[float] = []
    names: list[str] = []
    scene_of = []

    def observer(world, t):
        if not names:
            names.extend(n for n, b in world.scene.bodies.items() if not b.plane)
            scene_of.append(world.scene)
        if times and t <= times[-1]:
            return  # the final call repeats the last frame's time
        times.append(t)
        frames.append(np.stack([world.pose(n) for n in names]))

    result = simulate(scenario, values, parts, observer=observer, observe_every=every,
                      **simulate_kwargs)
    if not frames:
        return result, None
    scene = scene_of[0]
    runs = runs_of(scenario)
    palette = scene_colours(scene, runs)  # the colours of the PNG, the video and the report
    meshes, mesh_of, static, planes = scene_meshes(scene)
    solid = [b for b in scene.bodies.values() if not b.plane]
    colors = [palette[body.name] for body in solid]
    labels = [runs.get(body.object, body.object) for body in solid]
    seen = {e.name: e for e in result.events}
    events = tuple({"name": name, "after": list(spec.after), "join": spec.join,
                    "state": seen[name].state.value,
                    "time": seen[name].time, "description": spec.description}
                   for name, spec in scenario.events.items())
    return result, Replay(
        title=title or scenario.name, bodies=tuple(names), meshes=tuple(meshes),
        mesh_of=np.asarray(mesh_of), static=np.asarray(static, bool),
        colors=np.asarray(colors, float), planes=tuple(planes), times=np.asarray(times),
        poses=np.stack(frames), events=events, outcome=result.outcome.value,
        labels=tuple(labels))


def scene_meshes(scene) -> tuple[list, list[int], list[bool], list[np.ndarray]]:
    """What a replay draws of ``scene``'s bodies, planes aside, in the scene's order: each
    built mesh once ``(vertices, faces)``, the mesh of each body, whether each is static, and
    the planes' poses."""
    keys: dict[int, int] = {}
    meshes, mesh_of, static, planes = [], [], [], []
    for body in scene.bodies.values():
        if body.plane:
            planes.append(np.asarray(body.pose, float))
            continue
        k = keys.setdefault(id(body.built), len(meshes))
        if k == len(meshes):
            meshes.append((np.asarray(body.built.vertices, float),
                           np.asarray(body.built.faces, np.int64)))
        mesh_of.append(k)
        static.append(body.static)
    return meshes, mesh_of, static, planes


def _b64(array: np.ndarray, dtype: str) -> str:
    return base64.b64encode(np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<"))
                            .tobytes()).decode("ascii")


def _quaternions(R: np.ndarray) -> np.ndarray:
    """(..., 4) unit quaternions (x, y, z, w) of rotation matrices (..., 3, 3)."""
    from scipy.spatial.transform import Rotation

    shape = R.shape[:-2]
    q = Rotation.from_matrix(R.reshape(-1, 3, 3)).as_quat().reshape(*shape, 4)
    # one sign along each body's track, so interpolating between frames takes the short way
    for f in range(1, q.shape[0]):
        flip = np.einsum("...i,...i->...", q[f], q[f - 1]) < 0
        q[f][flip] *= -1
    return q


def replay_payload(replay: Replay) -> dict:
    """The JSON-ready form the viewer reads (see the module's docstring for the encoding)."""
    moving = np.flatnonzero(~replay.static)
    points = [transform_points(replay.poses[0, b], replay.meshes[replay.mesh_of[b]][0])
              for b in range(len(replay.bodies))]
    layout = np.vstack(points)  # the view frames the layout; bodies may fall far from it
    lo, hi = layout.min(axis=0), layout.max(axis=0)
    cloud = np.vstack([layout, replay.poses[:, moving, :3, 3].reshape(-1, 3)])
    a, b = cloud.min(axis=0), cloud.max(axis=0)
    centre, half = (a + b) / 2, np.maximum((b - a) / 2, 1e-6)
    track = replay.poses[:, moving]
    pos = np.round((track[..., :3, 3] - centre) / half * _Q)
    quat = np.round(_quaternions(track[..., :3, :3]) * _Q)
    first = replay.poses[0]
    # without labels, a body's name up to a '.' (a lever's axle) or '[' (a run's domino):
    # object and run names hold neither
    labels = replay.labels if replay.labels and len(replay.labels) == len(replay.bodies) \
        else [re.split(r"[.[]", n, maxsplit=1)[0] for n in replay.bodies]
    meshes = []
    for vertices, faces in replay.meshes:
        index = "u2" if len(vertices) < 65536 else "u4"
        meshes.append({"vertices": _b64(vertices, "f4"), "faces": _b64(faces, index),
                       "index": index})
    return {
        "title": replay.title,
        "outcome": replay.outcome,
        "bodies": [{"name": n, "mesh": int(replay.mesh_of[b]),
                    "color": [round(float(c), 3) for c in replay.colors[b]],
                    "static": bool(replay.static[b]), "label": labels[b],
                    "position": [float(v) for v in first[b, :3, 3]],
                    "quaternion": [float(v) for v in _quaternions(first[None, b, :3, :3])[0]]}
                   for b, n in enumerate(replay.bodies)],
        "meshes": meshes,
        "planes": [[float(v) for v in p.T.ravel()] for p in replay.planes],  # column-major
        "plane_colors": [list(plane_colour(p)) for p in replay.planes],
        "bounds": [lo.tolist(), hi.tolist()],
        "times": _b64(replay.times, "f4"),
        "duration": float(replay.times[-1]),
        "frames": len(replay.times),
        "moving": [int(b) for b in moving],
        "centre": centre.tolist(),
        "half": half.tolist(),
        "positions": _b64(np.clip(pos, -_Q, _Q), "i2"),  # (frames, moving, 3)
        "quaternions": _b64(np.clip(quat, -_Q, _Q), "i2"),  # (frames, moving, 4)
        "events": list(replay.events),
    }
