"""Pictures and videos of a layout, rendered on the CPU (pybullet's TinyRenderer).

Rendering is a view of the scene, apart from the simulation: a :class:`Renderer` holds an
engine of its own with only the parts' visual meshes (no physics body, so nothing to fight
over depth with), a floor and boards drawn as finite slabs, and a camera that frames the
layout. It draws any set of poses (a scene at rest, or a world's bodies while it runs, through
:func:`~rgmcad.sim.run.simulate`'s ``observer`` hook), smooth-shaded within curved faces and
flat across sharp edges, on a white background; stills are drawn at twice their size and
reduced (smooth edges; video frames are not, for speed). A scale bar and, on request, the
parts' names are drawn over them.
Videos are slowed down (a quarter of real time by default: a domino falls in a tenth of a
second) and show the simulated time and each event as it succeeds or fails.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from rgmcad.geometry import to_pybullet
from rgmcad.scene.bodies import Scene
from rgmcad.scene.palette import plane_colour, runs_of, scene_colours
from rgmcad.sim.causal import EventState
from rgmcad.sim.engine import Engine, pb

BEAD = 0.0015
"""Radius (m) of the beads a rope is drawn with (one every four radii along it)."""
MAX_SIDE = 16384
"""Largest side of a picture, pixels (callers choose their own, smaller limits)."""
SUPERSAMPLE_UP_TO = 4096
"""Pictures up to this side are drawn at twice the size and reduced (smooth edges)."""
DEFAULT_SPEED = 0.25
"""Playback speed of a video relative to real time."""
HOLD_END = 1.5
"""Seconds the last frame of a video stays, to read the outcome."""

_BACKGROUND = (255, 255, 255)
_SUCCESS, _FAILURE, _PENDING = (20, 130, 40), (200, 30, 30), (120, 120, 120)


def _shaded(vertices: np.ndarray, faces: np.ndarray):
    """(vertices, faces, normals) with normals smooth within curved faces, split at sharp
    edges (a box keeps flat sides, a ball is round)."""
    import trimesh

    mesh = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, int), process=False)
    smooth = mesh.smooth_shaded  # vertices split at edges sharper than trimesh's threshold
    return smooth.vertices, smooth.faces, smooth.vertex_normals


class Renderer:
    """Draws posed bodies of ``scene`` with a camera that frames them at rest.

    Parameters
    ----------
    scene : the layout (its poses place the camera and the floor).
    width, height : pixels of a picture.
    runs : object name -> its domino run's name (the dominoes of a run share a colour
        family: :mod:`rgmcad.scene.palette`, as in the replay and the report).
    supersample : draw at twice the size and reduce (smooth edges; four times the cost, so
        videos leave it out).
    """

    def __init__(self, scene: Scene, width: int = 640, height: int = 480,
                 runs: Mapping[str, str] | None = None, supersample: bool = True):
        if not (1 <= width <= MAX_SIDE and 1 <= height <= MAX_SIDE):  # pybullet would abort
            raise ValueError(f"picture size {width} x {height}: sides of 1 to {MAX_SIDE} pixels")
        self.scene = scene
        self.width, self.height = width, height
        self.scale = 2 if supersample and max(width, height) <= SUPERSAMPLE_UP_TO else 1
        self.engine = Engine()
        self.ghosts: dict[str, int] = {}
        self.colours = scene_colours(scene, runs)  # body name -> RGB in [0, 1]
        solid = [b for b in scene.bodies.values() if not b.plane]
        shaded: dict[int, tuple] = {}  # bodies of one built part (a run's dominoes) share it
        for body in solid:
            if id(body.built) not in shaded:
                shaded[id(body.built)] = _shaded(body.built.vertices, body.built.faces)
            v, f, n = shaded[id(body.built)]
            shape = self.engine.createVisualShape(
                pb.GEOM_MESH, vertices=v.tolist(), indices=f.ravel().tolist(),
                normals=n.tolist(), rgbaColor=(*self.colours[body.name], 1.0),
                specularColor=[0.15, 0.15, 0.15])
            self.ghosts[body.name] = self.engine.createMultiBody(0, -1, shape)
        self.posed = {name: body.pose for name, body in scene.bodies.items()}
        bead = self.engine.createVisualShape(pb.GEOM_SPHERE, radius=BEAD,
                                             rgbaColor=(0.25, 0.2, 0.15, 1.0))
        self.ropes = [(rope, [self.engine.createMultiBody(0, -1, bead) for _ in range(
            int(np.clip(rope.length / (4 * BEAD), 2, 400)))]) for rope in scene.ropes]
        points = np.vstack([b.world_vertices() for b in solid] or [np.zeros((1, 3))])
        self.lo, self.hi = points.min(axis=0), points.max(axis=0)
        for body in scene.bodies.values():
            if body.plane:
                self._slab(body.pose)
        self._camera()
        self.place({name: scene.bodies[name].pose for name in self.ghosts})

    def _slab(self, pose: np.ndarray) -> None:
        """An infinite plane drawn as a slab under the layout, three times its size."""
        normal, origin = pose[:3, 2], pose[:3, 3]
        centre = (self.lo + self.hi) / 2
        centre = centre - np.dot(centre - origin, normal) * normal  # onto the plane
        side = 3 * float(np.linalg.norm(self.hi - self.lo)) + 0.1
        thickness = 0.002
        shape = self.engine.createVisualShape(
            pb.GEOM_BOX, halfExtents=[side / 2, side / 2, thickness / 2],
            rgbaColor=(*plane_colour(pose), 1.0))
        placed = pose.copy()
        placed[:3, 3] = centre - normal * thickness / 2
        pos, orn = to_pybullet(placed)
        self.engine.createMultiBody(0, -1, shape, basePosition=pos, baseOrientation=orn)

    def _camera(self) -> None:
        centre = (self.lo + self.hi) / 2
        radius = float(np.linalg.norm(self.hi - self.lo)) / 2
        boards = [b for b in self.scene.bodies.values() if b.plane and abs(b.pose[2, 2]) < 0.5]
        if boards:  # look at the front of a vertical board, slightly from above
            direction = boards[0].pose[:3, 2] + np.array([0.0, 0.0, 0.15])
        else:
            direction = np.array([0.35, -1.0, 0.75])
        direction = direction / np.linalg.norm(direction)
        fov = 40.0
        distance = radius / np.tan(np.radians(fov / 2)) * 1.05
        self.eye, self.centre, self.fov = centre + direction * distance, centre, fov
        side = np.cross(direction, [0.0, 0.0, 1.0])
        self.light = (direction + np.array([0.0, 0.0, 0.9]) + 0.4 * side).tolist()  # front-lit
        self.view = pb.computeViewMatrix(self.eye.tolist(), centre.tolist(), [0, 0, 1])
        self.projection = pb.computeProjectionMatrixFOV(
            fov, self.width / self.height, distance / 20, distance * 3)

    def place(self, poses: Mapping[str, np.ndarray]) -> None:
        """Move the bodies named in ``poses`` (world (4, 4) poses of their part frames), and
        the ropes tied to them."""
        for name, pose in poses.items():
            pos, orn = to_pybullet(pose)
            self.engine.resetBasePositionAndOrientation(self.ghosts[name], pos, orn)
        self.posed.update(poses)
        for rope, beads in self.ropes:  # beads evenly spaced along the rope's path now
            points = rope.points.copy()
            for end, (body, local) in enumerate(zip(rope.bodies, rope.local, strict=True)):
                if body is not None:
                    pose = self.posed[body]
                    points[-end] = pose[:3, :3] @ local + pose[:3, 3]
            cum = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0),
                                                                  axis=1))])
            for bead, s in zip(beads, np.linspace(0.0, cum[-1], len(beads)), strict=True):
                k = min(int(np.searchsorted(cum, s, side="right")) - 1, len(points) - 2)
                t = (s - cum[k]) / max(cum[k + 1] - cum[k], 1e-12)
                at = points[k] + t * (points[k + 1] - points[k])
                self.engine.resetBasePositionAndOrientation(bead, at.tolist(), [0, 0, 0, 1])

    def project(self, points: np.ndarray) -> np.ndarray:
        """(n, 2) pixel coordinates (x right, y down) of world points (n, 3)."""
        view = np.asarray(self.view).reshape(4, 4).T
        proj = np.asarray(self.projection).reshape(4, 4).T
        p = np.c_[points, np.ones(len(points))] @ (proj @ view).T
        ndc = p[:, :2] / p[:, 3:4]
        return np.c_[(ndc[:, 0] + 1) / 2 * self.width, (1 - ndc[:, 1]) / 2 * self.height]

    def image(self, poses: Mapping[str, np.ndarray] | None = None) -> np.ndarray:
        """(height, width, 3) uint8 RGB picture, bodies at ``poses`` (default: as placed)."""
        if poses is not None:
            self.place(poses)
        w, h = self.width * self.scale, self.height * self.scale
        _, _, rgba, _, seg = self.engine.getCameraImage(
            w, h, self.view, self.projection, renderer=pb.ER_TINY_RENDERER,
            lightDirection=self.light, lightColor=[1, 1, 1], lightAmbientCoeff=0.55,
            lightDiffuseCoeff=0.5, lightSpecularCoeff=0.08, shadow=0)
        rgb = np.asarray(rgba, np.uint8).reshape(h, w, 4)[:, :, :3].copy()
        rgb[np.asarray(seg).reshape(h, w) < 0] = _BACKGROUND
        if self.scale == 1:
            return rgb
        from PIL import Image

        return np.asarray(Image.fromarray(rgb).reduce(self.scale))

    def close(self) -> None:
        self.engine.close()


# --- overlays ---------------------------------------------------------------------------------


def _font(size: int):
    from PIL import ImageFont

    return ImageFont.load_default(size=max(size, 8))


def scale_bar(renderer: Renderer, draw, text_size: int) -> tuple[float, float]:
    """A bar of a round length (mm) bottom left, true at the depth of the layout's centre;
    (its length in mm, in pixels)."""
    centre = renderer.centre
    right = np.cross(renderer.centre - renderer.eye, [0.0, 0.0, 1.0])
    right = right / (np.linalg.norm(right) or 1.0)
    a, b = renderer.project(np.array([centre, centre + right * 0.001]))
    px_per_mm = float(np.linalg.norm(b - a))
    goal = renderer.width / 6 / max(px_per_mm, 1e-9)
    length = min((s for s in (1, 2, 5, 10, 20, 50, 100, 200, 500, 1000, 2000)
                  if s >= goal * 0.6), default=2000)
    x0, y0 = int(renderer.width * 0.04), int(renderer.height - 2.2 * text_size)
    x1 = x0 + max(int(round(length * px_per_mm)), 1)
    thick = max(text_size // 5, 2)
    draw.rectangle([x0, y0, x1, y0 + thick], fill=(30, 30, 30))
    for x in (x0, x1):
        draw.rectangle([x - thick // 2, y0 - thick, x + thick // 2, y0 + 2 * thick],
                       fill=(30, 30, 30))
    label = f"{length / 10:g} cm" if length >= 100 else f"{length} mm"
    draw.text((x0, y0 - int(1.4 * text_size)), label, fill=(30, 30, 30), font=_font(text_size))
    return float(length), float(x1 - x0)


def labels(renderer: Renderer, scenario, draw, text_size: int,
           poses: Mapping[str, np.ndarray] | None = None) -> None:
    """Each object's name beside it (a domino run's once, at its first domino), the bodies
    at ``poses`` (default: at rest)."""
    font = _font(text_size)
    done, taken = set(), []
    for body in renderer.scene.bodies.values():
        if body.plane:
            continue
        obj = scenario.objects[body.object]
        name = obj.run or body.object
        if name in done:
            continue
        done.add(name)
        pose = body.pose if poses is None else poses[body.name]
        point = pose[:3, :3] @ body.built.centre_of_mass + pose[:3, 3]
        x, y = renderer.project(point[None])[0]
        tx, ty = x + 8, y - text_size - 8
        box = draw.textbbox((tx, ty), name, font=font)
        for _ in range(8):  # step down past the labels already drawn
            if not any(_overlap(box, other) for other in taken):
                break
            ty += text_size * 1.3
            box = draw.textbbox((tx, ty), name, font=font)
        taken.append(box)
        draw.line([(x, y), (tx, box[3] if ty > y else box[1] + text_size)], fill=(40, 40, 40))
        draw.rectangle([box[0] - 2, box[1] - 1, box[2] + 2, box[3] + 1], fill=(255, 255, 240),
                       outline=(90, 90, 90))
        draw.text((tx, ty), name, fill=(20, 20, 20), font=font)


def _overlap(a, b) -> bool:
    return a[0] < b[2] + 3 and b[0] < a[2] + 3 and a[1] < b[3] + 2 and b[1] < a[3] + 2


def _events_overlay(draw, events, t: float, final: bool, size: int, width: int) -> None:
    """The time, then each event behind a dot: hollow grey until it resolves, then filled
    green (success) or red (failure). Text has a white outline, readable over any part."""
    font = _font(size)
    halo = {"stroke_width": max(size // 8, 1), "stroke_fill": (255, 255, 255), "font": font}
    draw.text((width - 8 * size, size // 2), f"t = {t:.3f} s", fill=(20, 20, 20), **halo)
    y = size // 2
    for e in events:
        y += int(size * 1.3)
        done = e.state in (EventState.SUCCESS, EventState.FAILURE)
        resolved = done and (final or e.time is not None and e.time <= t + 1e-9)
        colour = (_SUCCESS if e.state is EventState.SUCCESS else _FAILURE) if resolved \
            else _PENDING
        r, cy = size * 0.35, y + size * 0.6
        draw.ellipse([size * 0.6 - r, cy - r, size * 0.6 + r, cy + r], outline=colour,
                     fill=colour if resolved else (255, 255, 255), width=max(size // 8, 1))
        draw.text((size * 1.3, y), e.name, fill=colour if resolved else (90, 90, 90), **halo)


def overlay(image: np.ndarray, draw_on) -> np.ndarray:
    from PIL import Image, ImageDraw

    picture = Image.fromarray(image)
    draw_on(ImageDraw.Draw(picture))
    return np.asarray(picture)


# --- files ------------------------------------------------------------------------------------


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


def _every(settings, fps: float, speed: float = DEFAULT_SPEED) -> int:
    """Simulation steps between two frames of a video played at ``speed``."""
    return max(1, int(round(speed / (fps * settings.timestep))))


def video_frames(settings, fps: float, speed: float = DEFAULT_SPEED) -> int:
    """Most frames :func:`record_video` keeps in memory for a scenario's ``settings``."""
    steps = int(round(settings.duration / settings.timestep))
    return steps // _every(settings, fps, speed) + 2 + int(HOLD_END * fps)


def record_video(scenario, values, parts, path: Path, fps: float, width: int, height: int,
                 speed: float = DEFAULT_SPEED, show_labels: bool = False, physics=None):
    """Simulate a layout and write a video of it (:func:`save_video`) played at ``speed``
    times real time (``fps`` adjusted so that a frame is a whole number of simulation
    steps), with the simulated time and the events overlaid; returns the
    :class:`~rgmcad.sim.run.SimulationResult`. Its frames are held in memory until then:
    at most :func:`video_frames` of ``height * width * 3`` bytes. ``physics``: a
    :class:`~rgmcad.scene.perturbation.PhysicsDraw` to simulate under (None: as designed)."""
    from rgmcad.scene.bodies import make_scene
    from rgmcad.sim.run import simulate

    renderer = Renderer(make_scene(scenario, values, parts), width, height, runs_of(scenario),
                        supersample=False)
    frames: list[tuple] = []

    def observer(world, t):
        poses = {n: world.pose(n) for n in renderer.ghosts}
        frames.append((t, renderer.image(poses), poses if show_labels else None))

    every = _every(scenario.settings, fps, speed)
    fps = speed / (every * scenario.settings.timestep)  # a whole number of steps a frame
    try:
        result = simulate(scenario, values, parts, observer=observer, observe_every=every,
                          physics=physics)
    finally:
        renderer.close()
    if not frames:
        return result
    size = max(height // 28, 10)
    out = []
    for i, (t, image, poses) in enumerate(frames):
        final = i == len(frames) - 1

        def draw(d, t=t, final=final, poses=poses):
            _events_overlay(d, result.events, t, final, size, width)
            scale_bar(renderer, d, size)
            if show_labels:
                labels(renderer, scenario, d, size, poses)
            d.text((size // 2, height - 1.3 * size), f"{speed:g}x", fill=(90, 90, 90),
                   font=_font(size))

        out.append(overlay(image, draw))
        frames[i] = (t, None, None)  # one copy of each frame in memory at a time
    out += [out[-1]] * int(HOLD_END * fps)  # the same array: no memory
    save_video(out, path, fps)
    return result


def render_png(scenario, scene: Scene, path: Path, width: int, height: int,
               show_labels: bool = False, show_scale: bool = True) -> tuple[float, float] | None:
    """Draw a posed scene (at rest, before any step) to a PNG file; the scale bar's length
    (mm, pixels), if drawn."""
    renderer = Renderer(scene, width, height, runs_of(scenario))
    try:
        image = renderer.image()
    finally:
        renderer.close()
    size = max(height // 40, 10)
    bar = []

    def draw(d):
        if show_scale:
            bar.append(scale_bar(renderer, d, size))
        if show_labels:
            labels(renderer, scenario, d, size)

    save_png(overlay(image, draw), path)
    return bar[0] if bar else None
