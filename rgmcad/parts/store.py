"""Built parts on disk: their ids, the folder they live in, reading them back, the manifest.

A built part lives in ``<directory>/<id>/`` (see :mod:`rgmcad.parts.build` for the files).
``<id>`` is :func:`part_id`: it changes when the parameters, the family's source file or
:data:`BUILD_VERSION` change, so stale builds are never reused. Infinite planes have no solid:
only ``part.json`` is written for them.

Reading (:meth:`PartStore.load`) uses json and numpy only: simulation workers never import
CadQuery. Loaded arrays are read-only: a :class:`PartStore` hands the same part to every
caller.

Every write goes to a temporary folder beside the final one and is renamed into place
(:meth:`PartStore.writing`), so a killed build never leaves half an artefact, and two
processes building the same part at once both end up with one complete copy.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rgmcad.errors import PartBuildError, ScenarioError
from rgmcad.files import write_json_atomic
from rgmcad.parts.family import MAIN, Family, Hinge, family_digest, params_dict
from rgmcad.parts.pieces import Piece, piece_from_dict

BUILD_VERSION = "1"
"""Part of every build id: bump it when the builder changes what it writes."""

DEFAULT_BUILD_DIR = Path("build/parts")
"""Where built parts go unless told otherwise (relative to the working directory)."""

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


def as_params(family: Family, params):
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
    params = as_params(family, params)
    text = family_digest(family) + canonical_params(params) + BUILD_VERSION
    return f"{family.name}-{hashlib.sha256(text.encode()).hexdigest()[:12]}"


# --- the store --------------------------------------------------------------------------------


class PartStore:
    """A folder of built parts, and the parts this object has loaded from it.

    A part loaded twice through one store is the same object (simulation keys derived caches
    on it), read from disk once. Pass one store to everything that loads parts in a process;
    a new store reads the files again.

    Parameters
    ----------
    directory : Path
        Folder of built parts (created on the first write).
    """

    def __init__(self, directory: Path | str = DEFAULT_BUILD_DIR):
        self.directory = Path(directory)
        self._loaded: dict[str, BuiltPart] = {}

    def __repr__(self) -> str:
        return f"PartStore({str(self.directory)!r}, {len(self._loaded)} loaded)"

    def has(self, pid: str) -> bool:
        """Whether part ``pid`` is loaded or built (its ``part.json`` exists)."""
        return pid in self._loaded or (self.directory / pid / "part.json").is_file()

    def load(self, pid: str) -> BuiltPart:
        """The part this store loaded before, else read from disk (FileNotFoundError if not
        built, :class:`DamagedPart` if its files cannot be read back)."""
        part = self._loaded.get(pid)
        if part is None:
            part = self._loaded[pid] = _read_part(self.directory / pid)
        return part

    def reload(self, pid: str) -> BuiltPart:
        """Read part ``pid`` from disk again (just built), replacing the one loaded before."""
        for attempt in range(5):  # a concurrent forced rebuild may be swapping the folder
            try:
                part = _read_part(self.directory / pid)
                break
            except FileNotFoundError:
                if attempt == 4:
                    raise
                time.sleep(0.05)
        self._loaded[pid] = part
        return part

    def forget(self) -> None:
        """Forget the parts loaded so far (the files stay)."""
        self._loaded.clear()

    @contextlib.contextmanager
    def writing(self, pid: str, *, replace: bool = True) -> Iterator[Path]:
        """A temporary folder to write part ``pid`` into, renamed to ``<directory>/<pid>`` when
        the block ends, deleted if it raises.

        A folder already there is replaced if ``replace`` (another process may have just made
        it), else kept and this one thrown away.
        """
        self.directory.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{pid}.", dir=self.directory))
        tmp.chmod(0o755)  # mkdtemp makes it private
        try:
            yield tmp
            _move_into_place(tmp, self.directory / pid, replace)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise


def as_store(where: PartStore | Path | str) -> PartStore:
    """``where`` if it is a store, else a new store of the folder ``where``."""
    return where if isinstance(where, PartStore) else PartStore(where)


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


def _frozen(array) -> np.ndarray:
    """The array made read-only: a store hands one loaded part to every caller."""
    array = np.asarray(array)
    array.flags.writeable = False
    return array


class DamagedPart(PartBuildError):
    """A built part whose files cannot be read back (cut short, edited, another program's):
    :func:`~rgmcad.parts.build.load_part` builds it again."""


def _read_part(folder: Path) -> BuiltPart:
    """The part built in ``folder``: FileNotFoundError if its ``part.json`` is not there
    (not built, or being replaced), :class:`DamagedPart` naming the file if a file cannot
    be read back as a part. ``mesh.npz`` is read without pickles: an object array in it is
    damage, never code run."""
    name = "part.json"
    try:
        record = json.loads((folder / name).read_text(encoding="utf-8"))
        bodies: dict[str, BuiltBody] = {}
        if record["bodies"]:
            name = "mesh.npz"
            with np.load(folder / name, allow_pickle=False) as arrays:
                for key, body in record["bodies"].items():
                    bodies[key] = BuiltBody(
                        key=key,
                        vertices=_frozen(_mesh(arrays[f"vertices_{key}"], np.floating)),
                        faces=_frozen(_mesh(arrays[f"faces_{key}"], np.integer)),
                        volume=float(body["volume"]),
                        centre_of_mass=_frozen(np.array(body["centre_of_mass"], float)),
                        inertia_unit=_frozen(np.array(body["inertia_unit"], float)),
                        bbox=_frozen(np.array(body["bbox"], float)),
                        pieces=tuple(piece_from_dict(p) for p in body["pieces"]),
                        fixed=bool(body["fixed"]),
                    )
                    _check_body(bodies[key])
            name = "part.json"
        joints = tuple(Hinge(j["moving"], j["fixed"], tuple(j["point"]), tuple(j["axis"]))
                       for j in record["joints"])
        files = {kind: folder / _plain_name(file) for kind, file in record["files"].items()}
        if record["id"] != folder.name:
            raise ValueError(f"id {record['id']!r} is not its folder's")
        return BuiltPart(id=str(record["id"]), family=str(record["family"]),
                         params=dict(record["params"]), bodies=bodies, joints=joints,
                         infinite=bool(record["infinite"]), files=files)
    except FileNotFoundError as exc:
        if name == "part.json":
            raise
        raise DamagedPart(folder / name, "", f"missing ({exc.strerror})") from None
    except Exception as exc:  # noqa: BLE001 - damage shows as any error of json or numpy
        why = " ".join(f"{type(exc).__name__}: {exc}".split())[:200]
        raise DamagedPart(folder / name, "", f"a damaged part cache entry ({why})") from None


def _mesh(array: np.ndarray, kind: type) -> np.ndarray:
    """``array`` if it is (n, 3) numbers of ``kind`` (float or integer)."""
    if array.ndim != 2 or array.shape[1] != 3 or not np.issubdtype(array.dtype, kind):
        raise ValueError(f"expected (n, 3) {kind.__name__} values, got {array.dtype} "
                         f"{array.shape}")
    return array


def _check_body(body: BuiltBody) -> None:
    n = len(body.vertices)
    if not (len(body.faces) and n >= 3 and np.isfinite(body.vertices).all()
            and body.faces.min() >= 0 and body.faces.max() < n):
        raise ValueError(f"body {body.key!r}: not a mesh ({n} vertices, {len(body.faces)} faces)")
    if not (math.isfinite(body.volume) and body.volume > 0 and body.bbox.shape == (2, 3)
            and body.centre_of_mass.shape == (3,) and body.inertia_unit.shape == (3, 3)):
        raise ValueError(f"body {body.key!r}: not its mass properties")


def _plain_name(name) -> str:
    if not (isinstance(name, str) and name and Path(name).name == name and name not in (".", "..")):
        raise ValueError(f"files: expected a file name, got {name!r}")
    return name


# --- manifest ---------------------------------------------------------------------------------


def _manifest_entry(part: BuiltPart, out_dir: Path) -> dict:
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
            "parts": [_manifest_entry(p, out_dir) for p in parts], **(extra or {})}
    return write_json_atomic(out_dir / _MANIFEST, data)
