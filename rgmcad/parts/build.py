"""Build part instances once, store them on disk, load them fast.

A *part instance* is a family plus its parameters. Building one runs the family's CadQuery
``build``, measures every body exactly with OpenCascade (volume, centre of mass, inertia
tensor, bounding box), tessellates it into a small watertight triangle mesh
(:mod:`rgmcad.parts.cad`), and writes into a :class:`~rgmcad.parts.store.PartStore`::

    <directory>/<id>/part.json   family, params, per-body mass properties, collision pieces, joints
                     mesh.npz    per body: vertices_<key> (n, 3) float64 m, faces_<key> (m, 3) int64
                     part.step   the CAD solids (an assembly, one child per body), in millimetres
                     part.stl    all bodies' meshes together, binary, in millimetres
                     part.glb    the assembly for viewers, in metres (glTF's unit, +Y up)

Loading (:func:`load_part`) reads ``part.json`` and ``mesh.npz`` with json and numpy only:
simulation workers never import CadQuery. Building imports it lazily.

Every function here takes the store to use, or a folder (a new store of its own). A part
loaded twice through one store is the same object.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import time
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from rgmcad.errors import PartBuildError
from rgmcad.parts import cad
from rgmcad.parts.family import MAIN, Family, params_dict
from rgmcad.parts.store import (
    BUILD_VERSION,
    DEFAULT_BUILD_DIR,
    FILES,
    UNITS,
    BuiltPart,
    DamagedPart,
    PartStore,
    as_params,
    as_store,
    canonical_params,
    part_id,
    write_manifest,
)

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

Store = PartStore | Path | str
"""Where parts are: a :class:`PartStore`, or a folder (a new store of that folder)."""


def build_part(family: Family, params, out_dir: Store = DEFAULT_BUILD_DIR, *,
               replace: bool = True) -> BuiltPart:
    """Build a part instance into ``<out_dir>/<id>/``.

    Parameters
    ----------
    family : Family
    params : params dataclass or mapping
        A mapping is validated with :meth:`Family.make_params`.
    out_dir : PartStore or Path
        The store of built parts, or its folder.
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
    params = as_params(family, params)
    pid = part_id(family, params)
    store = as_store(out_dir)
    start = time.perf_counter()
    with store.writing(pid, replace=replace) as tmp:
        if family.infinite:
            record = _record(family, params, pid, {}, {})
        else:
            record = _build_solid_part(family, params, pid, tmp)
        record["build_seconds"] = round(time.perf_counter() - start, 4)
        (tmp / "part.json").write_text(json.dumps(record, indent=1))
    log.info("built %s in %.2f s", pid, time.perf_counter() - start)
    return store.reload(pid)


def _build_solid_part(family: Family, params, pid: str, tmp: Path) -> dict:
    where = str(family.source or family.name)
    built = family.bodies_of(family.build(params))
    shapes = {k: cad.as_shape(s, where, k) for k, s in built.items()}
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
        volume, com, inertia = cad.mass_properties(shape)
        if not volume > 0:
            raise PartBuildError(where, "build", f"body {key!r} has no volume ({volume})")
        bbox = cad.exact_bbox(shape)
        vertices, faces, tolerance = cad.tessellate(shape, volume, bbox, where, key)
        body_pieces = pieces[key] if pieces is not None else cad.decompose(vertices, faces, bbox)
        meshes[key] = (vertices, faces)
        bodies[key] = {
            "volume": volume,
            "centre_of_mass": com.tolist(),
            "inertia_unit": inertia.tolist(),
            "bbox": bbox.tolist(),
            "fixed": key != MAIN,
            "pieces": [p.to_dict() for p in body_pieces],
            "triangles": len(faces),
            "tessellation": tolerance,
            "collision": "exact" if pieces is not None else "decomposed",
        }

    np.savez(tmp / "mesh.npz", **{f"{kind}_{key}": array for key, (v, f) in meshes.items()
                                  for kind, array in (("vertices", v), ("faces", f))})
    cad.write_stl(meshes, tmp / "part.stl")
    cad.write_assembly(shapes, pid, tmp / "part.step", tmp / "part.glb")
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


def load_part(family: Family, params, out_dir: Store = DEFAULT_BUILD_DIR, *,
              build_missing: bool = True) -> BuiltPart:
    """The built part instance: loaded before by the store, read from disk, or built now.

    Reading from disk uses json and numpy only (CadQuery is imported only to build).

    A part whose files cannot be read back (:class:`~rgmcad.parts.store.DamagedPart`: cut
    short, edited) counts as missing: built again over it, or raised if ``build_missing``
    is false.

    Raises
    ------
    FileNotFoundError
        The part was never built and ``build_missing`` is false.
    """
    params = as_params(family, params)
    pid = part_id(family, params)
    store = as_store(out_dir)
    if store.has(pid):
        try:
            return store.load(pid)
        except DamagedPart as exc:  # as if missing: built again, over the damaged one
            if not build_missing:
                raise
            log.warning("%s; building the part again", exc)
            try:
                return build_part(family, params, store, replace=True)
            except OSError as err:  # a read-only cache
                raise DamagedPart(exc.where, "", f"{exc.message}, and it cannot be built again "
                                  f"there ({err.strerror}); delete {store.directory / pid} or "
                                  "give another --build-dir") from None
    if build_missing:
        return build_part(family, params, store, replace=False)
    raise FileNotFoundError(f"part {pid} ({family.name} {canonical_params(params)}) is not "
                            f"built in {store.directory}; run `rgmcad build` first")


# --- many parts -------------------------------------------------------------------------------


def build_parts(instances: Iterable[tuple[Family, object]], out_dir: Store = DEFAULT_BUILD_DIR,
                *, progress: Callable[[int, int, str, bool], None] | None = None,
                force: bool = False, manifest: bool = True) -> list[BuiltPart]:
    """Build every distinct part instance not built yet, and write ``<out_dir>/manifest.json``
    (unless ``manifest`` is false).

    Parameters
    ----------
    instances : iterable of (Family, params)
        Params as dataclasses or mappings; duplicates (same id) are built once.
    out_dir : PartStore or Path
        The store of built parts, or its folder.
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
    store = as_store(out_dir)
    unique: dict[str, tuple[Family, object]] = {}
    for family, params in instances:
        params = as_params(family, params)
        unique.setdefault(part_id(family, params), (family, params))
    parts = []
    for done, (pid, (family, params)) in enumerate(unique.items(), start=1):
        cached = not force and store.has(pid)
        try:
            part = load_part(family, params, store, build_missing=False) if cached else None
        except DamagedPart as exc:
            log.warning("%s; building the part again", exc)
            cached = False
            part = build_part(family, params, store, replace=True)
        if part is None:
            part = build_part(family, params, store, replace=force)
        parts.append(part)
        if progress is not None:
            progress(done, len(unique), pid, cached)
    if manifest:
        write_manifest(parts, store.directory)
    return parts


def build_scenario_parts(scenarios, out_dir: Store = DEFAULT_BUILD_DIR, *,
                         progress: Callable[[int, int, str, bool], None] | None = None,
                         force: bool = False) -> list[BuiltPart]:
    """Build the parts of scenarios (:func:`build_parts`) and write the manifest once, with
    ``objects``: each scenario object's part id and, for moving bodies, its mass (kg) and
    inertia (kg m^2, about the centre of mass, part axes)."""
    store = as_store(out_dir)
    instances = [(s.family(o), o.params) for s in scenarios for o in s.body_objects()]
    parts = build_parts(instances, store, progress=progress, force=force, manifest=False)
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
    write_manifest(parts, store.directory, extra={"objects": objects})
    return parts
