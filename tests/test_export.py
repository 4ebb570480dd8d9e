"""``rgmcad export``: the posed layout as one CAD assembly that other CAD programs read back
with every part where the layout puts it."""

import json
from pathlib import Path

import numpy as np
import pytest

from rgmcad.cli import main
from rgmcad.geometry import invert, transform_points
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.layout_files import resolve_layout
from rgmcad.scene.loader import load_scenario

ROOT = Path(__file__).resolve().parent.parent
TOLERANCE_MM = 0.01


def _scene(name: str, layout: str):
    scenario = load_scenario(ROOT / "scenarios" / f"{name}.toml")
    _, values = resolve_layout(scenario, layout, None)
    return make_scene(scenario, values, load_parts(scenario))


def _children(assembly, found=None) -> dict:
    found = {} if found is None else found
    for child in assembly.children:
        found[child.name] = child
        _children(child, found)
    return found


def _exact_box(shape) -> np.ndarray:
    """(2, 3) bounding box of the exact geometry (not of a tessellation)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape.wrapped, box, False, False)
    return np.array(box.Get()).reshape(2, 3)


def test_exported_step_puts_every_named_part_at_its_layout_pose(tmp_path, caplog):
    import cadquery as cq
    from OCP.gp import gp_Trsf

    out = tmp_path / "cs.step"
    assert main(["-v", "export", "causality_switch", "--layout", "solved", "--out",
                 str(out)]) == 0
    assert "exported 69 bodies" in caplog.text  # -v says what was written
    scene = _scene("causality_switch", "solved")
    solids = {n: b for n, b in scene.bodies.items() if not b.plane}
    children = _children(cq.Assembly.importStep(str(out)))
    assert set(solids) <= set(children)
    for name, body in solids.items():
        child = children[name]
        shape = cq.Compound.makeCompound(list(child.shapes)).moved(child.loc)  # millimetres
        # its centre of mass where the layout puts the part's
        want = transform_points(body.pose, body.built.centre_of_mass[None])[0] * 1000
        got = np.array(cq.Shape.centerOfMass(shape).toTuple())
        assert np.abs(got - want).max() < TOLERANCE_MM, name
        # and turned as the layout turns it: moved back by the pose, its box is the part's own
        back = np.array(invert(body.pose))
        back[:3, 3] *= 1000
        trsf = gp_Trsf()
        trsf.SetValues(*back[0], *back[1], *back[2])
        got_box = _exact_box(shape.moved(cq.Location(trsf)))
        assert np.abs(got_box - body.built.bbox * 1000).max() < TOLERANCE_MM, name


def test_exported_glb_of_a_layout_file_names_every_part(tmp_path, capsys):
    import trimesh

    layout = tmp_path / "layout.json"
    layout.write_text(json.dumps({"scenario": "simple", "values": {
        "track.x": -0.12, "track.z": 0.08, "track.roll": 40}}))
    out = tmp_path / "simple.glb"
    assert main(["export", "simple", "--layout", str(layout), "--out", str(out)]) == 0
    assert str(layout) in capsys.readouterr().out
    scene = _scene("simple", str(layout))
    glb = trimesh.load(out, force="scene")
    names = {n: b for n, b in scene.bodies.items() if not b.plane}
    nodes = set(glb.graph.nodes)
    assert all(any(name in node for node in nodes) for name in names)
    everything = np.vstack([b.world_vertices() for b in names.values()])
    y_up = everything[:, [0, 2, 1]] * [1, 1, -1]  # glTF's axes: +Y up, +Z toward the viewer
    assert np.allclose(glb.bounds, [y_up.min(0), y_up.max(0)], atol=5e-4)
    # meshed to 0.1 mm, not to a fraction of each face: the 20 mm ball was 100,520 triangles
    faces = {n: len(m.faces) for n, m in glb.geometry.items()}
    assert sum(faces.values()) < 10_000, faces


def test_a_part_named_like_its_scenario_is_exported(tmp_path, capsys):
    # TEAPOT's teapot: the assembly is named after the scenario, and names must be unique
    text = (Path(__file__).resolve().parent.parent / "scenarios" / "simple.toml").read_text()
    scenario = tmp_path / "ball.toml"
    scenario.write_text(text.replace('name = "simple"', 'name = "ball"', 1))
    assert 'name = "ball"' in scenario.read_text()
    out = tmp_path / "ball.step"
    assert main(["export", str(scenario), "--layout", "solved", "--out", str(out)]) == 0
    assert out.stat().st_size > 0 and "ball" in out.read_text(errors="replace")


@pytest.mark.parametrize("out", ["x.stl", "x", "missing/x.step"])
def test_export_refuses_an_unusable_output_before_any_work(out, tmp_path, capsys):
    assert main(["export", "simple", "--out", str(tmp_path / out)]) == 2
    assert "--out" in capsys.readouterr().err
