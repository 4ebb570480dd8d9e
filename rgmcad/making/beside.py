"""Posts beside a raised part, for a part no stand fits under: a lever's axle, whose plank
swings through every place under it. A post is a block on the base plane against one end
face of the part (a face square to the base plane, the part's farthest point that way), its
top a little above the part; the axle's end goes into it (glue, or a hole drilled there).

It is a :class:`~rgmcad.making.placement.Site` like the stands under a part, whose top is
that height, whose contact is the strip of cells along the face, and whose cells on the
part's side of the face are closed.
"""

from __future__ import annotations

import numpy as np

from rgmcad.geometry import invert, matmul, transform_points
from rgmcad.making.placement import PlacementSettings, Site, block_static
from rgmcad.making.supports import Holding
from rgmcad.scene.bodies import Scene

__all__ = ["side_sites", "POST"]


POST = PlacementSettings(margin=0.0022, cell=0.0005)
"""A post keeps 2.2 mm from moving bodies (over the engine's 2 mm contact threshold: a
lever's axle often ends 2.5 mm beside its plank), on a 0.5 mm grid."""


def side_sites(scene: Scene, holding: Holding, settings: PlacementSettings = POST,
               above: float = 0.003, reach: float = 0.02) -> list[Site]:
    """The post sites of a raised part, one per end of each body's length (an axle's two
    ends) whose face is square to the base plane (within 17 degrees); its post's top
    ``above`` m over the part's highest point."""
    part, base = holding.part, holding.base
    bodies = [scene.bodies[n] for n in part.bodies]
    world = np.concatenate([b.world_vertices() for b in bodies])
    out = []
    for body in bodies:
        box = np.asarray(body.built.bbox, float)
        for axis in (int(np.argmax(box[1] - box[0])),):  # its ends along its length
            for side, sign in ((0, -1.0), (1, 1.0)):
                n = body.pose[:3, :3][:, axis] * sign
                if float(n @ base.normal) < -0.95:  # the end pointing at the base
                    out += _round_end(scene, holding, world, above, reach, settings)
                if abs(float(n @ base.normal)) > 0.3:
                    continue
                frame = base.frame()
                d = (frame[:3, :3].T @ n)[:2]
                d /= np.linalg.norm(d)
                turn = np.eye(4)
                turn[:2, :2] = [[d[0], -d[1]], [d[1], d[0]]]
                frame = matmul(frame, turn)
                local = transform_points(invert(frame), world)
                centre = box.mean(0)
                centre[axis] = box[side, axis]
                face = transform_points(matmul(invert(frame), body.pose), centre[None])[0]
                u_face = float(local[:, 0].max())
                if face[0] < u_face - 5e-4:  # not the part's end that way
                    continue
                out.append(_site(scene, holding, frame, local, u_face, above, reach, settings))
    return out


def _round_end(scene, holding, world, above, reach, settings) -> list[Site]:
    """Posts beside the end of an axle that points at the base (ballrun's lever, its end
    3.75 mm off the board): four sites, one each side of it, each a block on the base
    against the axle's side, its top ``above`` m over the axle's end."""
    out = []
    for d in ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)):
        turn = np.eye(4)
        turn[:2, :2] = [[d[0], -d[1]], [d[1], d[0]]]
        frame = matmul(holding.base.frame(), turn)
        local = transform_points(invert(frame), world)
        end = float(local[:, 2].min())
        near = local[local[:, 2] <= end + above]  # the axle's end, as high as the post
        out.append(_site(scene, holding, frame, near, float(near[:, 0].max()), above, reach,
                         settings, top=end + above))
    return out


def _site(scene, holding, frame, local, u_face, above, reach, settings, top=None) -> Site:
    lo, hi = local[:, :2].min(0) - reach, local[:, :2].max(0) + reach
    shape = tuple(int(k) for k in np.ceil((hi - lo) / settings.cell) + 1)
    top = np.array([0.0, 0.0, float(local[:, 2].max()) + above if top is None else top])
    site = Site(holding, frame, top, scene.bodies[holding.part.bodies[0]].pose.copy(), lo,
                shape, np.zeros(shape, bool), settings)
    uu, vv = site.cell_centres()
    c = settings.cell
    end = local[local[:, 0] >= u_face - 5e-4, 1]
    site.contact = (uu > u_face + 0.5 * c) & (uu <= u_face + 1.5 * c) & (
        vv >= end.min() - 0.5 * c) & (vv <= end.max() + 0.5 * c)
    site.blocked |= uu <= u_face + 0.5 * c  # the part's side of its face
    site.face_u, site.need_cells, site.free_size = u_face, 1, True
    block_static(scene, site)
    return site
