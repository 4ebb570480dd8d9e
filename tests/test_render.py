"""Pictures show the world as physics has it: every part's mesh where its body is (a moving
goblet's centre of mass is far from its frame), and every rope along its path."""

import numpy as np
import pybullet as pb
from _support import scene_of

from rgmcad.geometry import from_pybullet
from rgmcad.scene.loader import parse_scenario
from rgmcad.sim.render import Renderer
from rgmcad.sim.world import World

GOBLET = {"inner_height": 0.11, "top_radius": 0.036, "bottom_radius": 0.025, "wall": 0.002}


def test_meshes_and_ropes_are_drawn_where_the_bodies_are():
    sc = parse_scenario({
        "name": "picture",
        "objects": {
            "cup": {"part": "goblet", "params": GOBLET, "mass": 0.01,
                    "pose": {"x": 0.1, "z": 0.3, "roll": 180}},
            "lever": {"part": "lever", "mass": 0.02, "pose": {"x": -0.2, "z": 0.1, "roll": 10},
                      "params": {"length": 0.2, "width": 0.02, "thickness": 0.01,
                                 "pivot_x": 0.05}},
        },
        "ropes": {"r": {"ends": [{"object": "cup"}, {"object": "lever", "point": [-0.1, 0, 0]}],
                        "pulleys": [{"point": [0.1, 0, 0.5]}, {"point": [-0.3, 0, 0.5]}]}},
        "events": {"e": {"type": "contact", "first": "cup", "second": "lever"}},
    }, where="<test>")
    with World(scene_of(sc), sc.settings) as world:
        for _ in range(50):
            world.step()
        renderer = Renderer(world, 64, 64)
        renderer.image()
        cid = world.cid
        for (ghost, _), name in zip(renderer.ghosts, [n for n, b in world.scene.bodies.items()
                                                      if not b.plane], strict=True):
            base = from_pybullet(*pb.getBasePositionAndOrientation(ghost, physicsClientId=cid))
            local = pb.getVisualShapeData(ghost, physicsClientId=cid)[0]
            drawn = base @ from_pybullet(local[5], local[6])
            np.testing.assert_allclose(drawn, world.pose(name), atol=1e-6, err_msg=name)
        (rope, beads), = renderer.ropes
        at = np.array([pb.getBasePositionAndOrientation(b, physicsClientId=cid)[0] for b in beads])
        pose = world.pose("lever")
        hook = pose[:3, :3] @ [-0.1, 0, 0] + pose[:3, 3]
        np.testing.assert_allclose(at[0], world.pose("cup")[:3, 3], atol=1e-9)
        np.testing.assert_allclose(at[-1], hook, atol=1e-9)
        # the beads pass over both pulleys
        for pulley in ([0.1, 0, 0.5], [-0.3, 0, 0.5]):
            assert np.linalg.norm(at - pulley, axis=1).min() < 0.003
