"""A posed layout as one CAD assembly: STEP (millimetres) or GLB (glTF binary, metres).

Each body of the scene becomes one child of the assembly, named as in the scenario (``ball``,
``run[3]``, ``lever.axle`` for a part's second body), placed at its layout pose. The solids
are the parts' exact CAD solids, built again from their families (one build per distinct part
and a location per body), not meshes, so a workshop or a CAD program (FreeCAD, Onshape) gets
the true geometry. Infinite planes (the floor, a board) have no solid and are left out.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

import numpy as np

from rgmcad.files import naming
from rgmcad.making.stands import stand_solid
from rgmcad.parts.family import MAIN
from rgmcad.scene.bodies import Scene

log = logging.getLogger(__name__)

EXPORT_SUFFIXES = (".step", ".stp", ".glb")
"""File kinds :func:`export_layout` writes, chosen by the file's extension."""

_STATIC = (0.72, 0.70, 0.66)
_MOVING = (0.85, 0.33, 0.10)
_SUPPORT = (0.55, 0.62, 0.75)


def _location(pose: np.ndarray):
    """cq.Location of a (4, 4) pose in metres."""
    import cadquery as cq
    from OCP.gp import gp_Trsf

    trsf = gp_Trsf()
    m = np.asarray(pose, float)
    trsf.SetValues(*m[0, :4], *m[1, :4], *m[2, :4])
    return cq.Location(trsf)


def _solids(scenario, scene: Scene) -> dict[str, object]:
    """Body name -> its CadQuery solid in the part frame (metres), one build per part."""
    from rgmcad.parts.cad import as_shape
    from rgmcad.parts.store import as_params, part_id

    built: dict[str, dict] = {}
    out = {}
    for name, body in scene.bodies.items():
        if body.plane:
            continue
        obj = scenario.objects[body.object]
        family = scenario.family(obj)
        params = as_params(family, obj.params)
        pid = part_id(family, params)
        if pid not in built:
            where = str(family.source or family.name)
            built[pid] = {k: as_shape(s, where, k)
                          for k, s in family.bodies_of(family.build(params)).items()}
        key = MAIN if name == body.object else name.removeprefix(body.object + ".")
        out[name] = built[pid][key]
    return out


GLB_DEFLECTION_M = 1e-4
"""Largest distance between a GLB's triangles and the exact surface (0.1 mm)."""

GLB_ANGLE_RAD = 0.2
"""Largest angle between neighbouring triangles of a curved GLB surface."""


def _mesh(solids) -> None:
    """Triangulate each distinct solid to :data:`GLB_DEFLECTION_M`, an absolute distance.
    (CadQuery's own tolerance is relative to each face's size: 1e-4 of it made a 20 mm ball
    100,520 triangles and took 2.9 s; 0.1 mm takes about 2,000.)"""
    from OCP.BRepMesh import BRepMesh_IncrementalMesh

    for solid in {id(s): s for s in solids}.values():
        BRepMesh_IncrementalMesh(solid.wrapped, GLB_DEFLECTION_M, False, GLB_ANGLE_RAD, True)


def export_layout(scenario, scene: Scene, path: Path, stands=()) -> Path:
    """Write ``scene`` (a posed layout of ``scenario``) as one assembly to ``path``: STEP in
    millimetres for ``.step``/``.stp``, glTF binary (metres, as glTF wants) for ``.glb``.
    ``stands`` (:class:`~rgmcad.making.stands.Stand`) join it as ``support S1``, ... .

    Returns the path written. The file appears complete or not at all.
    """
    import cadquery as cq

    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in EXPORT_SUFFIXES:
        raise ValueError(f"{path}: expected one of {', '.join(EXPORT_SUFFIXES)}")
    # a name with a space: no part can have it (a part named like the scenario, teapot)
    assembly = cq.Assembly(name=f"{scenario.name} layout")
    solids = _solids(scenario, scene)
    for name, solid in solids.items():
        body = scene.bodies[name]
        colour = cq.Color(*(_STATIC if body.static else _MOVING))
        assembly.add(solid, name=name, loc=_location(body.pose), color=colour)
    for stand in stands:
        solids[f"support {stand.label}"] = solid = stand_solid(stand, mm=1.0)
        assembly.add(solid, name=f"support {stand.label}", color=cq.Color(*_SUPPORT))
    partial = path.with_name(f".{path.stem}.partial{suffix}")  # renamed when complete
    with naming(path):
        if suffix == ".glb":
            _mesh(solids.values())
            # the solids keep that triangulation: CadQuery meshes again only where the existing
            # one is coarser than asked, and its tolerance is relative to each face's size
            assembly.export(str(partial), tolerance=1.0, angularTolerance=1.0)
        else:
            assembly.export(str(partial), exportType="STEP", unit="M", outputUnit="MM")
        os.replace(partial, path)
    log.info("exported %d bodies to %s", len(assembly.children), path)
    return path
