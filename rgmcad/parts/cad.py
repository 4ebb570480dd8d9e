"""CadQuery and OpenCascade: exact mass properties, tessellation, CAD files, decomposition.

Only building imports this module (and CadQuery, lazily): loading a built part never does.

Meshes: the coarsest tessellation (OCC BRepMesh) whose volume is within 0.4 % of the exact
volume and which deviates at most 0.05 mm from the true surface, then degenerate triangles
removed and vertices merged; it is checked watertight with consistent outward winding.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from rgmcad.errors import PartBuildError
from rgmcad.parts.pieces import ConvexPiece, Piece

VOLUME_TOLERANCE = 0.004
"""Largest relative difference between a body's mesh volume and its exact volume."""

LINEAR_DEFLECTION_MAX = 5e-5
"""Largest linear deflection of a mesh from the true surface (m): 0.05 mm keeps a 2 mm wall
2 mm thick in the mesh. Parts are tabletop-sized; a curved part a metre across would get a
large mesh."""

ANGULAR_TOLERANCES = (0.2, 0.17, 0.15, 0.14, 0.13, 0.12, 0.11, 0.1, 0.08, 0.06, 0.05, 0.04)
"""Angular deflections (rad) tried in turn, coarsest first, until the mesh is watertight and
its volume is within VOLUME_TOLERANCE of the exact one. The linear deflection follows as
``min(size * angle**2 / 8, LINEAR_DEFLECTION_MAX)`` (the sagitta of that angle on a circle
the size of the body), with ``size`` the body's largest half extent."""


def as_shape(shape, where: str, key: str):
    """The CadQuery solid of a build's result (a Shape, or a Workplane holding one)."""
    import cadquery as cq

    if isinstance(shape, cq.Workplane):
        shape = shape.findSolid()
    if not isinstance(shape, cq.Shape) or not shape.isValid():
        raise PartBuildError(where, "build", f"body {key!r} is not a valid CadQuery solid")
    return shape


def mass_properties(shape) -> tuple[float, np.ndarray, np.ndarray]:
    """Exact volume (m^3), centre of mass (3,) and unit-density inertia (3, 3) from OCC."""
    from OCP.BRepGProp import BRepGProp
    from OCP.GProp import GProp_GProps

    props = GProp_GProps()
    BRepGProp.VolumeProperties_s(shape.wrapped, props)
    matrix = props.MatrixOfInertia()  # about the centre of mass, absolute axes
    inertia = np.array([[matrix.Value(i, j) for j in (1, 2, 3)] for i in (1, 2, 3)])
    centre = np.array(props.CentreOfMass().Coord())
    inertia = (inertia + inertia.T) / 2
    # Zero OCC's integration noise (1e-19 m on a centred box) for clean files and frames.
    size = float(props.Mass()) ** (1 / 3)
    centre[np.abs(centre) < 1e-12 * size] = 0.0
    inertia[np.abs(inertia) < 1e-12 * np.abs(inertia).max()] = 0.0
    return props.Mass(), centre, inertia


def exact_bbox(shape) -> np.ndarray:
    """(2, 3) tight bounding box of the solid's geometry (not of its triangulation)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape.wrapped, box, False, False)
    xmin, ymin, zmin, xmax, ymax, zmax = box.Get()
    return np.array([[xmin, ymin, zmin], [xmax, ymax, zmax]])


def tessellate(shape, volume: float, bbox: np.ndarray, where: str, key: str):
    """Watertight mesh of ``shape``: the coarsest of ANGULAR_TOLERANCES that is accurate."""
    import trimesh
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools

    size = float(np.max(bbox[1] - bbox[0])) / 2
    error = math.inf
    for angle in ANGULAR_TOLERANCES:
        linear = min(size * angle**2 / 8, LINEAR_DEFLECTION_MAX)
        BRepTools.Clean_s(shape.wrapped)
        BRepMesh_IncrementalMesh(shape.wrapped, linear, False, angle, False)
        mesh = trimesh.Trimesh(*_triangulation(shape), process=True)
        mesh.update_faces(mesh.nondegenerate_faces())
        mesh.remove_unreferenced_vertices()
        mesh.merge_vertices()
        if not (mesh.is_watertight and mesh.is_winding_consistent):
            continue
        if mesh.volume < 0:
            mesh.invert()
        error = abs(mesh.volume / volume - 1)
        if error <= VOLUME_TOLERANCE:
            vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float64)
            faces = np.ascontiguousarray(mesh.faces, dtype=np.int64)
            return vertices, faces, {"linear": linear, "angular": angle}
    raise PartBuildError(where, "build", f"body {key!r}: no watertight mesh within "
                        f"{VOLUME_TOLERANCE:.1%} of the solid's volume (last error {error:.2%})")


def _triangulation(shape) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) and outward triangles (m, 3) of a meshed shape, faces not yet merged."""
    from OCP.BRep import BRep_Tool
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    vertices, faces, offset = [], [], 0
    explorer = TopExp_Explorer(shape.wrapped, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face_s(explorer.Current())
        explorer.Next()
        location = TopLoc_Location()
        triangulation = BRep_Tool.Triangulation_s(face, location)
        if triangulation is None:
            continue
        trsf = location.Transformation()
        n = triangulation.NbNodes()
        vertices.append(np.array([triangulation.Node(i).Transformed(trsf).Coord()
                                  for i in range(1, n + 1)], dtype=np.float64).reshape(-1, 3))
        tri = np.array([triangulation.Triangle(i).Get()
                        for i in range(1, triangulation.NbTriangles() + 1)], dtype=np.int64)
        tri = tri.reshape(-1, 3) - 1 + offset
        faces.append(tri[:, ::-1] if face.Orientation() == TopAbs_REVERSED else tri)
        offset += n
    if not faces:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.concatenate(vertices), np.concatenate(faces)


def write_stl(meshes: dict, path: Path) -> None:
    import trimesh

    parts = [trimesh.Trimesh(v * 1000.0, f, process=False) for v, f in meshes.values()]
    trimesh.util.concatenate(parts).export(path, file_type="stl")


def write_assembly(shapes: dict, name: str, step: Path, glb: Path) -> None:
    """The bodies as one assembly (a child per body): STEP in millimetres, glTF in metres."""
    import cadquery as cq

    assembly = cq.Assembly(name=name)
    for key, shape in shapes.items():
        assembly.add(shape, name=key or "main")
    assembly.export(str(step), unit="M", outputUnit="MM")
    # The bodies keep the triangulation made by tessellate: CadQuery meshes again only when the
    # existing one is coarser than asked, and its tolerance here is relative to the size.
    assembly.export(str(glb), tolerance=1.0, angularTolerance=1.0)


# --- convex decomposition (families without exact collision pieces) ---------------------------


def decompose(vertices: np.ndarray, faces: np.ndarray, bbox: np.ndarray) -> list[Piece]:
    """Convex pieces approximating a mesh: CoACD if installed, else pybullet's V-HACD.

    Hull vertices are clipped to the body's bounding box (V-HACD's voxels overshoot a little).
    """
    try:
        import coacd
    except ImportError:
        hulls = _vhacd(vertices, faces)
    else:
        coacd.set_log_level("error")
        hulls = [v for v, _ in coacd.run_coacd(coacd.Mesh(vertices, faces))]
    return [ConvexPiece(np.clip(np.asarray(h, float), bbox[0], bbox[1]))
            for h in hulls if len(h) >= 4]


@contextlib.contextmanager
def _quiet_c_stdout():
    """Silence file descriptor 1 (C libraries print there, past sys.stdout)."""
    sys.stdout.flush()
    saved = os.dup(1)
    null = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
        os.close(null)


def _vhacd(vertices: np.ndarray, faces: np.ndarray) -> list[np.ndarray]:
    with tempfile.TemporaryDirectory() as folder:
        source, target = Path(folder, "in.obj"), Path(folder, "out.obj")
        lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in vertices.tolist()]
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces.tolist()]
        source.write_text("\n".join(lines) + "\n")
        with _quiet_c_stdout():
            import pybullet

            pybullet.vhacd(str(source), str(target), str(Path(folder, "log.txt")),
                           resolution=200000)
        hulls: list[list[list[float]]] = []
        for line in target.read_text().splitlines():
            if line.startswith("o "):
                hulls.append([])
            elif line.startswith("v "):
                if not hulls:
                    hulls.append([])
                hulls[-1].append([float(t) for t in line.split()[1:4]])
    return [np.array(h) for h in hulls]
