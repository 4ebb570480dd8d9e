"""What a part family is, and the registry of the families found in a ``parts/`` folder.

A part family is one Python file in ``parts/`` that defines ``FAMILY = Family(...)``:
typed parameters (a frozen dataclass, SI units), a pure ``build`` that returns the CadQuery
solid, and how physics sees the part: its collision pieces and the joints it brings. Adding a
family is adding a file; nothing in ``rgmcad/`` changes.

Family files must import CadQuery inside ``build`` only: simulation imports family files to
read parameters and collision pieces, and must not pay CadQuery's start-up cost.

A part is made of one or more rigid *bodies*. The main body has the key ``""`` and carries the
object's physical properties; other bodies (a lever's axle) are always static and are named
``<object>.<key>`` in a scene.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import inspect
import math
import reprlib
import sys
import types
import typing
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from rgmcad.errors import ScenarioError
from rgmcad.parts.pieces import (
    BoxPiece,
    CapsulePiece,
    ConvexPiece,
    CylinderPiece,
    Piece,
    PlanePiece,
    SpherePiece,
)
from rgmcad.shipped import shipped_dir

# Family files import the piece types from here: their source text is part of every build id
# (:func:`family_digest`), so moving that import would rename every built part.
__all__ = [
    "MAIN", "Family", "Hinge", "load_families", "family_digest", "params_dict", "DEFAULT_PARTS_DIR",
    "BoxPiece", "CapsulePiece", "ConvexPiece", "CylinderPiece", "Piece", "PlanePiece", "SpherePiece",
]

MAIN = ""
"""Key of a part's main body."""


# --- joints a part brings ---------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Hinge:
    """A revolute joint letting body ``moving`` turn about an axle fixed to body ``fixed``.

    ``point`` (3,) and ``axis`` (3,) are in the part's frame (metres, unit vector).
    """

    moving: str
    fixed: str
    point: tuple[float, float, float]
    axis: tuple[float, float, float]


# --- the family -------------------------------------------------------------------------------

Shape = typing.Any  # a CadQuery Shape/Workplane; not imported here on purpose


@dataclass(frozen=True, eq=False)
class Family:
    """A parametric part family.

    Attributes
    ----------
    name : registry key, used as ``part = "<name>"`` in scenario files.
    params : frozen dataclass type of the parameters (SI units; floats unless annotated).
    build : ``params -> Shape`` for a one-body part, or ``params -> {body_key: Shape}``.
    collision : ``params -> [Piece]`` or ``{body_key: [Piece]}``; exact convex pieces. ``None``
        asks the build for a convex decomposition of the mesh instead.
    joints : ``params -> [Hinge]`` the joints between the part's own bodies.
    volume : ``params -> float`` the analytic volume in m^3 of the main body (for tests).
    infinite : an infinite plane: no solid, no mesh; its collision piece is a PlanePiece.
    description : one line for ``rgmcad check`` and the docs.
    source : the family file (filled by the loader); its text enters the build cache key.
    source_digest : the hash of that text, taken once as the file is imported.
    """

    name: str
    params: type
    build: Callable[[typing.Any], Shape | dict[str, Shape]] | None
    collision: Callable[[typing.Any], Sequence[Piece] | dict[str, Sequence[Piece]]] | None
    joints: Callable[[typing.Any], Sequence[Hinge]] = lambda params: ()
    volume: Callable[[typing.Any], float] | None = None
    infinite: bool = False
    description: str = ""
    source: Path | None = None
    source_digest: str = ""

    def make_params(self, values: Mapping[str, typing.Any], *, where: str = "", key: str = ""):
        """Typed parameters from a mapping read from a file; bad input raises ScenarioError."""
        fields = {f.name: f for f in dataclasses.fields(self.params)}
        unknown = sorted(set(values) - set(fields))
        if unknown:
            raise ScenarioError(
                where, f"{key}.{unknown[0]}",
                f"unknown parameter of part {self.name!r}; allowed: {', '.join(fields)}",
            )
        hints = typing.get_type_hints(self.params)
        kwargs = {}
        for name, f in fields.items():
            if name not in values:
                if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                    raise ScenarioError(
                        where, f"{key}.{name}", f"missing parameter of part {self.name!r}"
                    )
                continue
            kwargs[name] = _coerce(values[name], hints.get(name, float), where, f"{key}.{name}",
                                   f.metadata)
        try:  # the family's own code: whatever it raises on odd values is the file's fault
            params = self.params(**kwargs)
            check = getattr(params, "check", None)
            problem = check() if check is not None else None
        except ScenarioError:
            raise
        except (TypeError, ValueError, ArithmeticError) as exc:
            problem = f"{type(exc).__name__}: {exc}"
        if problem:
            raise ScenarioError(where, key, f"part {self.name!r}: {problem}")
        return params

    def bodies_of(self, value) -> dict:
        """Normalise a one-body result (a shape or a piece list) to ``{body_key: value}``."""
        return dict(value) if isinstance(value, Mapping) else {MAIN: value}

    def collision_pieces(self, params) -> dict[str, list[Piece]] | None:
        if self.collision is None:
            return None
        return {k: list(v) for k, v in self.bodies_of(self.collision(params)).items()}

    def fixed_bodies(self, params) -> tuple[str, ...]:
        """Body keys other than the main one: always static (axles and the like)."""
        if self.collision is not None:
            keys = self.bodies_of(self.collision(params)).keys()
        else:
            keys = (MAIN,)
        return tuple(k for k in keys if k != MAIN)


FLOAT_RANGE = (-100.0, 100.0)
"""Default range of a float parameter (SI units: metres, a part of at most 100 m). A family
widens or narrows it per field: ``field(metadata={"range": (low, high)})``; a field that is not
a length says so with ``metadata={"unit": "deg"}`` (lengths are also 0 or at least
:data:`FINEST` in size, and the loader warns of those above 2 m as likely millimetres)."""
FINEST = 1e-5
"""The smallest non-zero length of a part (0.01 mm): finer is no size a part can have, and
makes volumes, masses and inertias vanish."""
INT_RANGE = (-1000, 1000)
"""Default range of an int parameter (a count of sectors, say: its cost grows with it)."""

_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxlist, _REPR.maxstring, _REPR.maxother = 2, 4, 40, 40


def _coerce(value, annotation, where: str, key: str, metadata=None):
    """``value`` as the parameter's type: a finite float or an int within the field's
    ``metadata["range"]`` (default :data:`FLOAT_RANGE` / :data:`INT_RANGE`), a bool, a string,
    a tuple of those."""
    metadata = metadata or {}
    if annotation in (float, "float", int, "int"):
        integer = annotation in (int, "int")
        low, high = metadata.get("range") or (INT_RANGE if integer else FLOAT_RANGE)
        kind = "an integer" if integer else "a number"
        if (isinstance(value, bool) or not isinstance(value, int if integer else int | float)
                or isinstance(value, float) and not math.isfinite(value)
                or not low <= value <= high):
            raise ScenarioError(where, key, f"expected {kind} with {low:,g} <= {key.rpartition('.')[2]}"
                                f" <= {high:,g}, got {_REPR.repr(value)}")
        if not integer and metadata.get("unit", "m") == "m" and 0 < abs(value) < FINEST:
            raise ScenarioError(where, key, f"expected 0 or a length of at least {FINEST:g} m, "
                                f"got {value!r}")
        return value if integer else float(value)
    if annotation in (bool, "bool"):
        if not isinstance(value, bool):
            raise ScenarioError(where, key, f"expected true or false, got {_REPR.repr(value)}")
        return value
    if annotation in (str, "str"):
        if not isinstance(value, str):
            raise ScenarioError(where, key, f"expected a string, got {_REPR.repr(value)}")
        return value
    origin = typing.get_origin(annotation)
    if origin is tuple:
        args = typing.get_args(annotation)
        if not isinstance(value, list | tuple) or len(value) != len(args):
            raise ScenarioError(where, key, f"expected a list of {len(args)} numbers, "
                                f"got {_REPR.repr(value)}")
        return tuple(_coerce(v, a, where, key, metadata) for v, a in zip(value, args, strict=True))
    if origin in (typing.Union, types.UnionType):  # ``float | None``: TOML has no None
        options = [a for a in typing.get_args(annotation) if a is not type(None)]
        if len(options) == 1:
            return _coerce(value, options[0], where, key, metadata)
    return value


def params_dict(params) -> dict:
    """JSON-ready dict of a parameter dataclass."""
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(params).items()}


# --- registry ---------------------------------------------------------------------------------

DEFAULT_PARTS_DIR = shipped_dir("parts")


def load_families(parts_dir: Path | None = None) -> dict[str, Family]:
    """A fresh registry ``{name: Family}`` of every ``*.py`` in ``parts_dir``.

    Each file must define ``FAMILY``; a file without it, or two families with one name, is an
    error naming the file. A file is imported once per process, like any module, so every
    registry of one folder holds the same families and parameter classes (parameters read
    through one registry stay valid, and picklable, after another is loaded).
    """
    parts_dir = Path(parts_dir or DEFAULT_PARTS_DIR)
    families: dict[str, Family] = {}
    for path in sorted(parts_dir.glob("*.py")):
        if path.name.startswith("_"):
            continue
        family = _import_family(path)
        if family.name in families:
            raise ScenarioError(str(path), "FAMILY.name", f"family {family.name!r} defined twice")
        families[family.name] = family
    return families


def _import_family(path: Path) -> Family:
    """The ``FAMILY`` of a family file, its ``source`` filled in; imported on first use."""
    module_name = f"rgmcad_parts_{path.stem}_{_digest(str(path))[:8]}"
    module = sys.modules.get(module_name)
    if module is None:
        spec = importlib.util.spec_from_file_location(module_name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[module_name] = module  # dataclasses need the module registered
        try:
            spec.loader.exec_module(module)
        except BaseException as exc:  # the file's own code: its fault, in one line
            del sys.modules[module_name]
            if isinstance(exc, KeyboardInterrupt):  # Ctrl-C: the user's, not the file's
                raise
            raise _import_error(path, exc) from None
        family = getattr(module, "FAMILY", None)
        if isinstance(family, Family):
            module.FAMILY = dataclasses.replace(family, source=path, source_digest=_digest(
                path.read_text(encoding="utf-8", errors="surrogateescape")))
    family = getattr(module, "FAMILY", None)
    if not isinstance(family, Family):
        raise ScenarioError(str(path), "FAMILY", "a part file must define FAMILY = Family(...)")
    if not (isinstance(family.params, type) and dataclasses.is_dataclass(family.params)):
        raise ScenarioError(str(path), "FAMILY.params", "expected a dataclass of the part's "
                            f"parameters, got {_REPR.repr(family.params)}")
    return family


def _import_error(path: Path, exc: BaseException) -> ScenarioError:
    """One line for a part file that cannot be imported: its file and line (the line of
    that file where the error arose, or the import in it that led there) and the error."""
    import traceback

    if isinstance(exc, SyntaxError) and exc.filename and exc.lineno:
        where, what = f"{exc.filename}:{exc.lineno}", f"syntax error: {exc.msg}"
    else:
        lines = [f.lineno for f in traceback.extract_tb(exc.__traceback__)
                 if Path(f.filename) == path and f.lineno]
        where = f"{path}:{lines[-1]}" if lines else str(path)
        what = (f"it exits Python: SystemExit({exc.code!r})" if isinstance(exc, SystemExit)
                else ": ".join(filter(None, [type(exc).__name__, " ".join(str(exc).split())[:200]])))
    return ScenarioError(where, "", f"importing this part family file failed ({what}); a "
                         "part file must run without error and define FAMILY = Family(...)")


def family_digest(family: Family) -> str:
    """Hash of the family's source file: part of every build cache key."""
    if family.source_digest:
        return family.source_digest
    text = family.source.read_text() if family.source else inspect.getsource(family.build)
    return _digest(text)


def _digest(text: str) -> str:
    return hashlib.sha256(text.encode("utf-8", "surrogateescape")).hexdigest()
