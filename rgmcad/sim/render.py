"""Pictures and videos of a layout, rendered on the CPU with pybullet's TinyRenderer.

Rendering is separate from simulation: it adds visual shapes (the parts' CAD meshes) to a
world only when asked, and watches a simulation through its ``observer`` hook.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from rgmcad.geometry import to_pybullet
from rgmcad.scene.bodies import Scene
from rgmcad.sim.engine import pb
from rgmcad.sim.world import World

BEAD = 0.0015
"""Radius (m) of the beads a rope is drawn with."""
MAX_SIDE = 16384
"""Largest side of a picture, pixels (callers choose their own, smaller limits)."""
_STATIC = (0.72, 0.70, 0.66, 1.0)
_PALETTE = [(0.85, 0.33, 0.10, 1), (0.13, 0.47, 0.71, 1), (0.17, 0.63, 0.17, 1),
            (0.58, 0.40, 0.74, 1), (0.89, 0.47, 0.76, 1), (0.74, 0.74, 0.13, 1),
            (0.09, 0.75, 0.81, 1), (0.55, 0.34, 0.29, 1)]


class Renderer:
    """Draws a world: adds a visual copy of every body's mesh and a camera that frames them.

    pybullet cannot attach a visual shape to an existing body, so each body gets a massless,
    collision-free ghost that is moved onto it before each picture.
    """

    def __init__(self, world: World, width: int = 640, height: int = 480):
        if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):  # pybullet would abort
            raise ValueError(f"picture size {width} x {height}: sides of 1 to {MAX_SIDE} pixels")
        self.world = world
        self.width, self.height = width, height
        self.ghosts: list[tuple[int, object]] = []
        engine = world.engine
        for i, (name, body) in enumerate(world.scene.bodies.items()):
            if body.plane:
                continue  # an infinite plane would hide the view; the background stands for it
            h = world.handles[name]
            color = _STATIC if body.static else _PALETTE[i % len(_PALETTE)]
            pos, orn = to_pybullet(h.com_to_part)  # the part frame in the COM frame
            shape = engine.createVisualShape(
                pb.GEOM_MESH, vertices=np.asarray(body.built.vertices, float).tolist(),
                indices=np.asarray(body.built.faces, int).ravel().tolist(), rgbaColor=color,
                visualFramePosition=pos, visualFrameOrientation=orn)
            ghost = engine.createMultiBody(0, -1, shape)
            self.ghosts.append((ghost, h))
        bead = engine.createVisualShape(pb.GEOM_SPHERE, radius=BEAD, rgbaColor=(0.1, 0.1, 0.1, 1))
        self.ropes = [(rope, [engine.createMultiBody(0, -1, bead) for _ in range(
            min(400, int(np.ceil(rope.length / (2 * BEAD))) + 1))]) for rope in world.scene.ropes]
        self._camera(world.scene)

    def _camera(self, scene: Scene) -> None:
        points = np.vstack([b.world_vertices() for b in scene.bodies.values() if not b.plane])
        lo, hi = points.min(axis=0), points.max(axis=0)
        centre = (lo + hi) / 2
        radius = float(np.linalg.norm(hi - lo)) / 2
        boards = [b for b in scene.bodies.values() if b.plane and abs(b.pose[2, 2]) < 0.5]
        if boards:  # look at the front of a vertical board, slightly from above
            direction = boards[0].pose[:3, 2] + np.array([0.0, 0.0, 0.15])
        else:
            direction = np.array([0.35, -1.0, 0.75])
        direction = direction / np.linalg.norm(direction)
        fov = 40.0
        distance = radius / np.tan(np.radians(fov / 2)) * 1.05
        eye = centre + direction * distance
        self.view = pb.computeViewMatrix(eye.tolist(), centre.tolist(), [0, 0, 1])
        self.projection = pb.computeProjectionMatrixFOV(
            fov, self.width / self.height, distance / 50, distance * 4)

    def image(self) -> np.ndarray:
        """(height, width, 3) uint8 RGB picture of the world now."""
        engine = self.world.engine
        for ghost, h in self.ghosts:
            if h.link < 0:
                pos, orn = engine.getBasePositionAndOrientation(h.uid)
            else:
                pos, orn = engine.getLinkState(h.uid, h.link)[:2]
            engine.resetBasePositionAndOrientation(ghost, pos, orn)
        for rope, beads in self.ropes:  # beads evenly spaced along the rope's path now
            points = rope.points.copy()
            for i, (body, local) in enumerate(zip(rope.bodies, rope.local, strict=True)):
                if body is not None:
                    pose = self.world.pose(body)
                    points[0 if i == 0 else -1] = pose[:3, :3] @ local + pose[:3, 3]
            cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
            for bead, s in zip(beads, np.linspace(0.0, cum[-1], len(beads)), strict=True):
                k = min(int(np.searchsorted(cum, s, side="right")) - 1, len(points) - 2)
                t = (s - cum[k]) / max(cum[k + 1] - cum[k], 1e-12)
                at = points[k] + t * (points[k + 1] - points[k])
                engine.resetBasePositionAndOrientation(bead, at.tolist(), [0, 0, 0, 1])
        _, _, rgba, _, _ = engine.getCameraImage(
            self.width, self.height, self.view, self.projection,
            renderer=pb.ER_TINY_RENDERER, lightDirection=[0.4, -0.6, 1.0], shadow=0)
        return np.asarray(rgba, np.uint8).reshape(self.height, self.width, 4)[:, :, :3]


def save_png(image: np.ndarray, path: Path) -> None:
    from PIL import Image

    Image.fromarray(image).save(path)


def save_video(frames: list[np.ndarray], path: Path, fps: float) -> None:
    """MP4 (needs imageio-ffmpeg) or, for a ``.gif`` path, an animated GIF."""
    path = Path(path)
    if path.suffix.lower() == ".gif":
        from PIL import Image

        images = [Image.fromarray(f) for f in frames]
        images[0].save(path, save_all=True, append_images=images[1:],
                       duration=int(1000 / fps), loop=0)
        return
    import imageio.v2 as imageio

    with imageio.get_writer(path, fps=fps, codec="libx264", quality=7,
                            macro_block_size=8) as writer:
        for frame in frames:
            writer.append_data(frame)


def _every(settings, fps: float) -> int:
    """Simulation steps between two frames of a video."""
    return max(1, int(round(1 / (fps * settings.timestep))))


def video_frames(settings, fps: float) -> int:
    """Most frames :func:`record_video` keeps in memory for a scenario's ``settings``."""
    return int(round(settings.duration / settings.timestep)) // _every(settings, fps) + 2


def record_video(scenario, values, parts, path: Path, fps: float, width: int, height: int):
    """Simulate a layout and write a video of it (:func:`save_video`); returns the
    :class:`~rgmcad.sim.run.SimulationResult`. Its frames are held in memory until then:
    at most :func:`video_frames` of ``height * width * 3`` bytes."""
    from rgmcad.sim.run import simulate

    renderer, frames = [], []

    def observer(world, t):
        if not renderer:
            renderer.append(Renderer(world, width, height))
        frames.append(renderer[0].image())

    every = _every(scenario.settings, fps)
    result = simulate(scenario, values, parts, observer=observer, observe_every=every)
    if frames:
        save_video(frames, path, fps)
    return result


def render_png(scene: Scene, settings, path: Path, width: int, height: int) -> None:
    """Draw a posed scene (at rest, before any step) to a PNG file."""
    with World(scene, settings) as world:
        save_png(Renderer(world, width, height).image(), path)
