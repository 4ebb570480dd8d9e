"""Layout files, read and written in one place.

A layout file (JSON, or TOML for reading) holds ``scenario = "<name>"`` and either ``values``
(``{"track.x": -0.1, ...}``, metres and degrees; parameters left out keep the scenario file's
value) or ``vector`` (the normalised design vector); optionally ``tolerances``
(``{"object.component": [down, up]}``, real units) and anything else a writer adds (``poses``,
``probability``, ...). Every command's ``--layout NAME|FILE`` and ``--vector`` go through
:func:`resolve_layout`.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np

from rgmcad.errors import ScenarioError, UsageError
from rgmcad.geometry import POSE_KEYS
from rgmcad.scene.design_space import (
    local_poses,
    values_from_mapping,
    values_from_vector,
)
from rgmcad.scene.loader_checks import key_text, read_text
from rgmcad.scene.schema import POSE, VECTOR, show


def _read(path: Path) -> object:
    text = read_text(path, "layout file")
    try:
        return tomllib.loads(text) if path.suffix == ".toml" else json.loads(text)
    except (ValueError, RecursionError) as exc:
        reason = "nested too deeply" if isinstance(exc, RecursionError) else exc
        raise ScenarioError(str(path), "", f"cannot read the layout file ({reason})") from None


def resolve_layout(scenario, layout: str | None, vector: str | None):
    """(name, real values (d,)) of ``--layout NAME|FILE`` or ``--vector v1,...,vd``; a layout
    file is named by its path as given (``runs/simple-s0/layout.json``), since every run's
    file has the same stem."""
    where = str(scenario.path)
    if vector is not None:
        try:
            v = np.array([float(x) for x in vector.split(",")], float)
        except ValueError:
            raise UsageError("--vector", "", "expected comma-separated numbers") from None
        if v.shape != (scenario.dimension,):
            raise UsageError("--vector", "", f"expected {scenario.dimension} values "
                                f"(the design space of {scenario.name}), got {len(v)}")
        if not np.all(np.isfinite(v)) or np.any(v < 0) or np.any(v > 1):
            raise UsageError("--vector", "", "values must be numbers in [0, 1]")
        return "vector", values_from_vector(scenario, v)
    name = "initial" if layout is None else layout  # "" names nothing (Path("") is ".")
    if name in scenario.layouts:
        return name, values_from_mapping(scenario, scenario.layouts[name])
    path = Path(name)
    if not name or not path.is_file():
        raise ScenarioError(where, "layouts", f"unknown layout {name!r}: not a layout of this "
                            f"scenario ({', '.join(scenario.layouts)}) nor a file")
    return name, load_layout_file(scenario, path)


def load_layout_file(scenario, path: Path) -> np.ndarray:
    """Real values (d,) from a layout file (JSON or TOML) with ``values`` or ``vector``."""
    data = _read(path)
    if not isinstance(data, dict):
        raise ScenarioError(str(path), "", "a layout file holds a table")
    if data.get("scenario") not in (None, scenario.name):
        raise ScenarioError(str(path), "scenario", f"this layout is for {show(data['scenario'])}, "
                            f"not {scenario.name!r}")
    if "values" in data:
        values = data["values"]
        if not isinstance(values, dict):
            raise ScenarioError(str(path), "values", "expected a table of parameter: value")
        free = {f.name: f for f in scenario.free}
        read = {}
        for k, v in values.items():
            if k not in free:
                raise ScenarioError(str(path), f"values.{key_text(k)}", "not a free parameter; "
                                    "allowed: " + ", ".join(sorted(free)))
            read[k] = POSE[free[k].component].read(v, str(path), f"values.{k}")
        return values_from_mapping(scenario, read)
    if "vector" in data:
        v = data["vector"]
        if not isinstance(v, list) or len(v) != scenario.dimension:
            raise ScenarioError(str(path), "vector", f"expected {scenario.dimension} numbers, "
                                f"each {VECTOR.describe('v')}, got {show(v)}")
        return values_from_vector(scenario, np.array(
            [VECTOR.read(x, str(path), f"vector[{i}]") for i, x in enumerate(v)], float))
    raise ScenarioError(str(path), "", "a layout file needs `values` or `vector`")


def layout_document(scenario, x, **extra) -> dict:
    """A layout file (usable as ``--layout FILE``): the scenario's name, the normalised
    ``vector``, the real ``values`` (metres and degrees), and the parent-relative ``poses`` of
    the objects with free parameters; ``extra`` keys are added."""
    x = np.asarray(x, dtype=float)
    values = values_from_vector(scenario, x)
    poses = local_poses(scenario, values)
    moved = dict.fromkeys(f.object for f in scenario.free)
    return {
        "scenario": scenario.name,
        "vector": [float(v) for v in x],
        "values": {f.name: float(v) for f, v in zip(scenario.free, values, strict=True)},
        "poses": {obj: {"parent": scenario.objects[obj].parent,
                        **{k: float(v) for k, v in zip(POSE_KEYS, poses[obj], strict=True)}}
                  for obj in moved},
        **extra,
    }


def read_hand_note(path: Path) -> str:
    """A layout file's ``built_by_hand`` line (how often it works when built by hand, as the
    optimiser measured it): printable characters only, at most 200; "" when absent or not a
    string."""
    data = _read(path)
    note = data.get("built_by_hand") if isinstance(data, dict) else None
    if not isinstance(note, str):
        return ""
    return "".join(c for c in note if c.isprintable())[:200]


def read_push_against(scenario, path: Path) -> dict[str, dict[str, str]]:
    """A layout file's ``push_against`` table (``{"object.component": {"low" | "high":
    object}}``, as the optimiser writes it): only entries naming a free parameter and an
    object of ``scenario``; others are left out (they only change words on a template)."""
    data = _read(path)
    table = data.get("push_against") if isinstance(data, dict) else None
    if not isinstance(table, dict):
        return {}
    free = {f.name for f in scenario.free}
    return {key: {side: part for side, part in sides.items()
                  if side in ("low", "high") and part in scenario.objects}
            for key, sides in table.items() if key in free and isinstance(sides, dict)}


def read_tolerances(scenario, path: Path) -> dict[str, tuple[float, float]]:
    """``{"object.component": (down, up)}`` from a layout file's ``tolerances`` table.

    Values are real units (metres, degrees), both non-negative. A file without the table
    gives ``{}``.

    Raises
    ------
    ScenarioError
        The table, a key or a value is malformed.
    """
    data = _read(path)
    if not isinstance(data, dict) or "tolerances" not in data:
        return {}
    table = data["tolerances"]
    if not isinstance(table, dict):
        raise ScenarioError(str(path), "tolerances", 'expected a table {"object.component": '
                            "[down, up]} in metres and degrees")
    out: dict[str, tuple[float, float]] = {}
    for key, value in table.items():
        obj, _, component = str(key).rpartition(".")
        if obj not in scenario.objects or component not in POSE_KEYS:
            raise ScenarioError(str(path), f"tolerances.{key_text(key)}", "expected object.component with "
                                f"a component of {', '.join(POSE_KEYS)} and an object of "
                                f"{scenario.name} ({', '.join(scenario.objects)})")
        if isinstance(value, int | float) and not isinstance(value, bool):
            value = [value, value]
        if (not isinstance(value, list) or len(value) != 2
                or any(isinstance(v, bool) or not isinstance(v, int | float) for v in value)
                or not all(math.isfinite(v) for v in value)):
            raise ScenarioError(str(path), f"tolerances.{key}", "expected [down, up] (two "
                                "numbers, metres or degrees) or one number")
        out[key] = (abs(float(value[0])), abs(float(value[1])))
    return out
