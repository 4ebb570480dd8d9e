"""Build part instances once, store them on disk, load them fast.

A *part instance* is a family plus its parameters. Building one runs the family's CadQuery
``build``, measures every body exactly with OpenCascade (volume, centre of mass, inertia
tensor, bounding box), tessellates it into a small watertight triangle mesh, and writes::

    <out_dir>/<id>/part.json   family, params, per-body mass properties, collision pieces, joints
                   mesh.npz    per body: vertices_<key> (n, 3) float64 m, faces_<key> (m, 3) int64
                   part.step   the CAD solids (an assembly, one child per body), in millimetres
                   part.stl    all bodies' meshes together, binary, in millimetres
                   part.glb    the assembly for viewers, in metres (glTF's unit, +Y up)

``<id>`` is :func:`part_id`: it changes when the parameters, the family's source file or
:data:`BUILD_VERSION` change, so stale builds are never reused. Infinite planes have no solid:
only ``part.json`` is written for them.

Loading (:func:`load_part`) reads ``part.json`` and ``mesh.npz`` with json and numpy only:
simulation workers never import CadQuery. Building imports it lazily.

Meshes: the coarsest tessellation (OCC BRepMesh) whose volume is within 0.4 % of the exact
volume and which deviates at most 0.05 mm from the true surface, then degenerate triangles
removed and vertices merged; it is checked watertight with consistent outward winding. Loaded
arrays are read-only (they are shared through an in-process cache).

Every write goes to a temporary folder beside the final one and is renamed into place, so a
killed build never leaves half an artefact, and two processes building the same part at once
both end up with one complete copy.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import logging
import math
import os
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rgmcad.errors import PartBuildError, ScenarioError
from rgmcad.parts.family import (
    MAIN,
    ConvexPiece,
    Family,
    Hinge,
    Piece,
    family_digest,
    params_dict,
    piece_from_dict,
    piece_to_dict,
)

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

BUILD_VERSION = "1"
"""Part of every build id: bump it when this module changes what it writes."""

DEFAULT_BUILD_DIR = Path("build/parts")
"""Where built parts go unless told otherwise (relative to the working directory)."""

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

UNITS = {
    "length": "m",
    "volume": "m^3",
    "inertia_unit": "kg m^2 for a density of 1 kg/m^3",
    "mesh.npz": "m",
    "step": "mm",
    "stl": "mm",
    "glb": "m",
}
"""Units of the numbers in ``part.json``/``manifest.json`` and of the files."""

FILES = ("step", "stl", "glb")

_MANIFEST = "manifest.json"


# --- results ----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class BuiltBody:
    """One rigid body of a built part.

    Attributes
    ----------
    key : str
        Body key: ``""`` for the main body, else e.g. ``"axle"``.
    vertices : (n, 3) float64
        Mesh vertices in the part frame, metres.
    faces : (m, 3) int64
        Triangles indexing ``vertices``; the mesh is watertight with outward normals.
    volume : float
        Exact volume of the CAD solid, m^3.
    centre_of_mass : (3,) float64
        Exact centre of mass (uniform density) in the part frame, metres.
    inertia_unit : (3, 3) float64
        Inertia tensor about the centre of mass, part-frame axes, for a density of 1 kg/m^3
        (kg m^2). For a body of mass ``m``: ``inertia_unit * m / volume``.
    bbox : (2, 3) float64
        Exact axis-aligned bounding box of the solid in the part frame: rows min and max, m.
    pieces : tuple of Piece
        Convex collision pieces, frames in the part frame.
    fixed : bool
        Whether the body is always static (every body but the main one).
    """

    key: str
    vertices: np.ndarray
    faces: np.ndarray
    volume: float
    centre_of_mass: np.ndarray
    inertia_unit: np.ndarray
    bbox: np.ndarray
    pieces: tuple[Piece, ...]
    fixed: bool

    def inertia(self, mass: float) -> np.ndarray:
        """(3, 3) inertia tensor about the centre of mass for a body of ``mass`` kg."""
        return self.inertia_unit * (mass / self.volume)


@dataclass(frozen=True, eq=False)
class BuiltPart:
    """A built part instance, as loaded from its folder.

    Attributes
    ----------
    id : str
        ``<family>-<12 hex digits>``, see :func:`part_id`; also the folder name.
    family : str
        Family name.
    params : dict
        The parameters, JSON-ready (:func:`rgmcad.parts.family.params_dict`).
    bodies : dict of str to BuiltBody
        Keyed by body key, main body ``""`` first; empty for an infinite plane.
    joints : tuple of Hinge
        Joints between the part's own bodies, in the part frame.
    infinite : bool
        An infinite plane: no bodies and no files.
    files : dict of str to Path
        ``"step"``, ``"stl"``, ``"glb"`` to existing files; empty for an infinite plane.
    """

    id: str
    family: str
    params: dict
    bodies: dict[str, BuiltBody]
    joints: tuple[Hinge, ...]
    infinite: bool
    files: dict[str, Path] = field(default_factory=dict)

    @property
    def main(self) -> BuiltBody:
        """The main body (key ``""``)."""
        return self.bodies[MAIN]


# --- identity ---------------------------------------------------------------------------------


def _as_params(family: Family, params):
    """The family's params dataclass from an instance or a mapping (validated)."""
    if isinstance(params, family.params):
        problem = getattr(params, "check", lambda: None)()
        if problem:
            raise ScenarioError(str(family.source or family.name), "", f"part {family.name!r}: "
                                f"{problem}")
        return params
    if isinstance(params, Mapping):
        return family.make_params(params, where=str(family.source or family.name))
    raise TypeError(f"parameters of part {family.name!r} must be a {family.params.__name__} or a "
                    f"mapping, not {type(params).__name__}")


def _canonical(value):
    if isinstance(value, float):
        return value + 0.0  # -0.0 and 0.0 are one part
    if isinstance(value, dict):
        return {k: _canonical(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_canonical(v) for v in value]
    return value


def canonical_params(params) -> str:
    """Canonical JSON text of a parameter dataclass (sorted keys, no spaces, exact floats)."""
    return json.dumps(_canonical(params_dict(params)), sort_keys=True, separators=(",", ":"),
                      allow_nan=False)


def part_id(family: Family, params) -> str:
    """Build id of a part instance: ``f"{family.name}-{hash[:12]}"``.

    The hash is the SHA-256 of the family's source digest, the canonical JSON of ``params``
    (a params dataclass or a mapping) and :data:`BUILD_VERSION`.
    """
    params = _as_params(family, params)
    text = family_digest(family) + canonical_params(params) + BUILD_VERSION
    return f"{family.name}-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


# --- building ---------------------------------------------------------------------------------


def build_part(family: Family, params, out_dir: Path = DEFAULT_BUILD_DIR, *,
               replace: bool = True) -> BuiltPart:
    """Build a part instance into ``<out_dir>/<id>/``.

    Parameters
    ----------
    family : Family
    params : params dataclass or mapping
        A mapping is validated with :meth:`Family.make_params`.
    out_dir : Path
        Folder of built parts.
    replace : bool
        Replace a build already there (another process may have just made it). If false, the
        one there is kept and this build is thrown away.

    Returns
    -------
    BuiltPart
        As :func:`load_part` would load it.

    Raises
    ------
    ScenarioError
        Bad parameters, or a family whose build or collision pieces are inconsistent.
    """
    params = _as_params(family, params)
    pid = part_id(family, params)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix=f".{pid}.", dir=out_dir))
    tmp.chmod(0o755)  # mkdtemp makes it private
    try:
        if family.infinite:
            record = _record(family, params, pid, {}, {})
        else:
            record = _build_solid_part(family, params, pid, tmp)
        record["build_seconds"] = round(time.perf_counter() - start, 4)
        (tmp / "part.json").write_text(json.dumps(record, indent=1))
        _move_into_place(tmp, out_dir / pid, replace)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    log.info("built %s in %.2f s", pid, time.perf_counter() - start)
    for attempt in range(5):  # a concurrent forced rebuild may be swapping the folder
        try:
            part = _read_part(out_dir / pid)
            break
        except FileNotFoundError:
            if attempt == 4:
                raise
            time.sleep(0.05)
    _CACHE[_cache_key(out_dir, pid)] = part
    return part


def _move_into_place(tmp: Path, final: Path, replace: bool) -> None:
    """Rename the finished temporary folder to its final name.

    A folder already there is replaced if ``replace``, else kept (and ``tmp`` deleted).
    """
    try:
        os.rename(tmp, final)
        return
    except OSError:
        if not final.exists():
            raise
    if not replace and (final / "part.json").is_file():
        shutil.rmtree(tmp, ignore_errors=True)
        return
    # An older (or concurrent) build is there: swap it out, then delete it.
    trash = Path(tempfile.mkdtemp(prefix=f".{final.name}.old.", dir=final.parent))
    try:
        os.rename(final, trash / "part")
    except FileNotFoundError:
        pass  # another process moved it away first
    try:
        os.rename(tmp, final)
    except OSError:
        if not (final / "part.json").exists():
            raise
        shutil.rmtree(tmp, ignore_errors=True)  # a concurrent build won; it is just as good
    shutil.rmtree(trash, ignore_errors=True)


def _build_solid_part(family: Family, params, pid: str, tmp: Path) -> dict:
    import cadquery as cq

    where = str(family.source or family.name)
    built = family.bodies_of(family.build(params))
    shapes = {k: _as_shape(cq, s, where, k) for k, s in built.items()}
    if MAIN not in shapes:
        raise PartBuildError(where, "build", 'build must return the main body (key "")')
    shapes = {MAIN: shapes.pop(MAIN), **shapes}
    pieces = family.collision_pieces(params)
    if pieces is not None and set(pieces) != set(shapes):
        raise PartBuildError(where, "collision", f"collision bodies {sorted(pieces)} differ from "
                            f"build bodies {sorted(shapes)}")

    bodies: dict[str, dict] = {}
    meshes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for key, shape in shapes.items():
        volume, com, inertia = _mass_properties(shape)
        if not volume > 0:
            raise PartBuildError(where, "build", f"body {key!r} has no volume ({volume})")
        bbox = _exact_bbox(shape)
        vertices, faces, tolerance = _tessellate(shape, volume, bbox, where, key)
        body_pieces = pieces[key] if pieces is not None else _decompose(vertices, faces, bbox)
        meshes[key] = (vertices, faces)
        bodies[key] = {
            "volume": volume,
            "centre_of_mass": com.tolist(),
            "inertia_unit": inertia.tolist(),
            "bbox": bbox.tolist(),
            "fixed": key != MAIN,
            "pieces": [piece_to_dict(p) for p in body_pieces],
            "triangles": len(faces),
            "tessellation": tolerance,
            "collision": "exact" if pieces is not None else "decomposed",
        }

    np.savez(tmp / "mesh.npz", **{f"{kind}_{key}": array for key, (v, f) in meshes.items()
                                  for kind, array in (("vertices", v), ("faces", f))})
    _write_stl(meshes, tmp / "part.stl")
    assembly = cq.Assembly(name=pid)
    for key, shape in shapes.items():
        assembly.add(shape, name=key or "main")
    assembly.export(str(tmp / "part.step"), unit="M", outputUnit="MM")
    # The bodies keep the triangulation made above: CadQuery meshes again only when the
    # existing one is coarser than asked, and its tolerance here is relative to the size.
    assembly.export(str(tmp / "part.glb"), tolerance=1.0, angularTolerance=1.0)
    return _record(family, params, pid, bodies, {k: f"part.{k}" for k in FILES})


def _record(family: Family, params, pid: str, bodies: dict, files: dict) -> dict:
    return {
        "id": pid,
        "family": family.name,
        "params": params_dict(params),
        "build_version": BUILD_VERSION,
        "infinite": bool(family.infinite),
        "units": UNITS,
        "bodies": bodies,
        "joints": [dataclasses.asdict(j) for j in family.joints(params)],
        "files": files,
    }


def _as_shape(cq, shape, where: str, key: str):
    if isinstance(shape, cq.Workplane):
        shape = shape.findSolid()
    if not isinstance(shape, cq.Shape) or not shape.isValid():
        raise PartBuildError(where, "build", f"body {key!r} is not a valid CadQuery solid")
    return shape


def _mass_properties(shape) -> tuple[float, np.ndarray, np.ndarray]:
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


def _exact_bbox(shape) -> np.ndarray:
    """(2, 3) tight bounding box of the solid's geometry (not of its triangulation)."""
    from OCP.Bnd import Bnd_Box
    from OCP.BRepBndLib import BRepBndLib

    box = Bnd_Box()
    BRepBndLib.AddOptimal_s(shape.wrapped, box, False, False)
    xmin, ymin, zmin, xmax, ymax, zmax = box.Get()
    return np.array([[xmin, ymin, zmin], [xmax, ymax, zmax]])


def _tessellate(shape, volume: float, bbox: np.ndarray, where: str, key: str):
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


def _write_stl(meshes: dict, path: Path) -> None:
    import trimesh

    parts = [trimesh.Trimesh(v * 1000.0, f, process=False) for v, f in meshes.values()]
    trimesh.util.concatenate(parts).export(path, file_type="stl")


# --- convex decomposition (families without exact collision pieces) ---------------------------


def _decompose(vertices: np.ndarray, faces: np.ndarray, bbox: np.ndarray) -> list[Piece]:
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


# --- loading ----------------------------------------------------------------------------------

_CACHE: dict[tuple[str, str], BuiltPart] = {}


def _cache_key(out_dir: Path, pid: str) -> tuple[str, str]:
    return os.path.abspath(out_dir), pid


def clear_cache() -> None:
    """Forget the parts loaded in this process (the files stay)."""
    _CACHE.clear()


def load_part(family: Family, params, out_dir: Path = DEFAULT_BUILD_DIR, *,
              build_missing: bool = True) -> BuiltPart:
    """The built part instance, from this process's cache, from disk, or built now.

    Reading from disk uses json and numpy only (CadQuery is imported only to build).

    Raises
    ------
    FileNotFoundError
        The part was never built and ``build_missing`` is false.
    """
    params = _as_params(family, params)
    pid = part_id(family, params)
    key = _cache_key(out_dir, pid)
    part = _CACHE.get(key)
    if part is not None:
        return part
    folder = Path(out_dir) / pid
    if (folder / "part.json").is_file():
        part = _read_part(folder)
    elif build_missing:
        return build_part(family, params, out_dir, replace=False)
    else:
        raise FileNotFoundError(f"part {pid} ({family.name} {canonical_params(params)}) is not "
                                f"built in {out_dir}; run `rgmcad build` first")
    _CACHE[key] = part
    return part


def _frozen(array) -> np.ndarray:
    """The array made read-only: loaded parts are shared through the process cache."""
    array = np.asarray(array)
    array.flags.writeable = False
    return array


def _read_part(folder: Path) -> BuiltPart:
    record = json.loads((folder / "part.json").read_text())
    bodies: dict[str, BuiltBody] = {}
    if record["bodies"]:
        with np.load(folder / "mesh.npz", allow_pickle=False) as arrays:
            for key, body in record["bodies"].items():
                bodies[key] = BuiltBody(
                    key=key,
                    vertices=_frozen(arrays[f"vertices_{key}"]),
                    faces=_frozen(arrays[f"faces_{key}"]),
                    volume=float(body["volume"]),
                    centre_of_mass=_frozen(np.array(body["centre_of_mass"], float)),
                    inertia_unit=_frozen(np.array(body["inertia_unit"], float)),
                    bbox=_frozen(np.array(body["bbox"], float)),
                    pieces=tuple(piece_from_dict(p) for p in body["pieces"]),
                    fixed=bool(body["fixed"]),
                )
    joints = tuple(Hinge(j["moving"], j["fixed"], tuple(j["point"]), tuple(j["axis"]))
                   for j in record["joints"])
    return BuiltPart(
        id=record["id"],
        family=record["family"],
        params=record["params"],
        bodies=bodies,
        joints=joints,
        infinite=bool(record["infinite"]),
        files={kind: folder / name for kind, name in record["files"].items()},
    )


# --- many parts -------------------------------------------------------------------------------


def build_parts(instances: Iterable[tuple[Family, object]], out_dir: Path = DEFAULT_BUILD_DIR,
                *, progress: Callable[[int, int, str, bool], None] | None = None,
                force: bool = False, manifest: bool = True) -> list[BuiltPart]:
    """Build every distinct part instance not built yet, and write ``<out_dir>/manifest.json``
    (unless ``manifest`` is false).

    Parameters
    ----------
    instances : iterable of (Family, params)
        Params as dataclasses or mappings; duplicates (same id) are built once.
    out_dir : Path
    progress : callable, optional
        ``progress(done, total, id, cached)`` after each distinct part; ``cached`` is true when
        the part was already built.
    force : bool
        Rebuild even the parts already built.

    Returns
    -------
    list of BuiltPart
        One per distinct instance, in first-seen order; the manifest lists the same.
    """
    out_dir = Path(out_dir)
    unique: dict[str, tuple[Family, object]] = {}
    for family, params in instances:
        params = _as_params(family, params)
        unique.setdefault(part_id(family, params), (family, params))
    parts = []
    for done, (pid, (family, params)) in enumerate(unique.items(), start=1):
        cached = not force and (
            _cache_key(out_dir, pid) in _CACHE or (out_dir / pid / "part.json").is_file()
        )
        if cached:
            part = load_part(family, params, out_dir, build_missing=False)
        else:
            part = build_part(family, params, out_dir, replace=force)
        parts.append(part)
        if progress is not None:
            progress(done, len(unique), pid, cached)
    if manifest:
        write_manifest(parts, out_dir)
    return parts


def build_scenario_parts(scenarios, out_dir: Path = DEFAULT_BUILD_DIR, *,
                         progress: Callable[[int, int, str, bool], None] | None = None,
                         force: bool = False) -> list[BuiltPart]:
    """Build the parts of scenarios (:func:`build_parts`) and write the manifest once, with
    ``objects``: each scenario object's part id and, for moving bodies, its mass (kg) and
    inertia (kg m^2, about the centre of mass, part axes)."""
    out_dir = Path(out_dir)
    instances = [(s.family(o), o.params) for s in scenarios for o in s.body_objects()]
    parts = build_parts(instances, out_dir, progress=progress, force=force, manifest=False)
    by_id = {p.id: p for p in parts}
    objects = {}
    for s in scenarios:
        for o in s.body_objects():
            pid = part_id(s.family(o), o.params)
            main = by_id[pid].bodies.get(MAIN)
            entry = {"part": pid}
            if main is not None and not o.physical.static:
                mass = o.physical.mass or o.physical.density * main.volume
                entry.update(mass=mass, inertia=(main.inertia_unit * mass / main.volume).tolist())
            objects[f"{s.name}/{o.name}"] = entry
    write_manifest(parts, out_dir, extra={"objects": objects})
    return parts


def manifest_entry(part: BuiltPart, out_dir: Path) -> dict:
    """JSON-ready summary of a built part for ``manifest.json`` (file paths relative to it)."""
    return {
        "id": part.id,
        "family": part.family,
        "params": part.params,
        "infinite": part.infinite,
        "bodies": {
            key: {
                "volume": body.volume,
                "centre_of_mass": body.centre_of_mass.tolist(),
                "inertia_unit": body.inertia_unit.tolist(),
                "bbox": body.bbox.tolist(),
                "fixed": body.fixed,
            }
            for key, body in part.bodies.items()
        },
        "files": {kind: os.path.relpath(path, out_dir) for kind, path in part.files.items()},
    }


def write_manifest(parts: Iterable[BuiltPart], out_dir: Path = DEFAULT_BUILD_DIR,
                   extra: Mapping | None = None) -> Path:
    """Write ``<out_dir>/manifest.json`` atomically; ``extra`` adds top-level keys."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    data = {"build_version": BUILD_VERSION, "units": UNITS,
            "parts": [manifest_entry(p, out_dir) for p in parts], **(extra or {})}
    path = out_dir / _MANIFEST
    fd, tmp = tempfile.mkstemp(prefix=".manifest.", suffix=".json", dir=out_dir)
    try:
        with os.fdopen(fd, "w") as handle:
            json.dump(data, handle, indent=1)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise
    return path
