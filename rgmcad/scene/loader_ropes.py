"""The ``[ropes.NAME]`` tables of a scenario file, read into :class:`~rgmcad.scene.model.Rope`.

::

    [ropes.gate_rope]
    ends = [{ object = "cage" }, { object = "gate", point = [-0.05875, 0, 0] }]
    pulleys = [{ point = [-0.32, 0, 0.29] }, { point = [0, 0, 0.29] }]
    length = 0.5      # m; or slack = 0.01: the initial length plus 1 cm

Each end and pulley is a point in the part frame of ``object`` (a frame, a body), or in the
world without ``object``. Errors name the file, the key and what is allowed.
"""

from __future__ import annotations

from rgmcad.errors import ScenarioError
from rgmcad.scene.loader_checks import check_keys, check_name, expect, key_text
from rgmcad.scene.model import Rope, RopePoint, SceneObject
from rgmcad.scene.schema import MAX_PULLEYS, MAX_ROPES, ROPE, show

ROPE_KEYS = ("ends", "pulleys", "length", "slack", "note")
POINT_KEYS = ("object", "point")


def parse_ropes(raw, objects: dict[str, SceneObject], where: str) -> dict[str, Rope]:
    raw = expect(raw, dict, where, "ropes")
    if len(raw) > MAX_ROPES:
        raise ScenarioError(where, "ropes", f"{len(raw):,} ropes; at most {MAX_ROPES:,}")
    ropes = {}
    for name, table in raw.items():
        key = f"ropes.{key_text(name)}"
        check_name(name, where, key)
        table = expect(table, dict, where, key)
        check_keys(table, ROPE_KEYS, where, key)
        ends = expect(table.get("ends"), list, where, f"{key}.ends")
        if len(ends) != 2:
            raise ScenarioError(where, f"{key}.ends", "a rope has two ends: a list of two "
                                f"{{ object = NAME, point = [x, y, z] }} tables, got {show(ends)}")
        ends = tuple(_point(e, objects, where, f"{key}.ends[{i}]") for i, e in enumerate(ends))
        if not any(e.object is not None and not objects[e.object].physical.static for e in ends):
            raise ScenarioError(where, f"{key}.ends", "neither end is on a moving body (an "
                                "object with a mass or density): the rope would do nothing")
        pulleys = expect(table.get("pulleys", []), list, where, f"{key}.pulleys")
        if len(pulleys) > MAX_PULLEYS:
            raise ScenarioError(where, f"{key}.pulleys", f"{len(pulleys):,} pulleys; at most "
                                f"{MAX_PULLEYS:,} per rope")
        pulleys = tuple(_point(p, objects, where, f"{key}.pulleys[{i}]", fixed=True)
                        for i, p in enumerate(pulleys))
        if "length" in table and "slack" in table:
            raise ScenarioError(where, key, "give length (m) or slack (m, added to the initial "
                                "length), not both")
        length = ROPE["length"].read(table["length"], where, f"{key}.length") \
            if "length" in table else None
        slack = ROPE["slack"].read(table.get("slack", 0.0), where, f"{key}.slack")
        if "note" in table:
            expect(table["note"], str, where, f"{key}.note")
        ropes[name] = Rope(name, ends, pulleys, length, slack)
    return ropes


def _point(raw, objects, where, key, fixed=False) -> RopePoint:
    raw = expect(raw, dict, where, key)
    check_keys(raw, POINT_KEYS, where, key)
    obj = raw.get("object")
    if obj is not None:
        if not isinstance(obj, str) or obj not in objects:
            raise ScenarioError(where, f"{key}.object", f"unknown object {show(obj)}; allowed: "
                                "any object or frame (a run's domino: NAME[i])")
        if fixed and not objects[obj].physical.static:
            raise ScenarioError(where, f"{key}.object", f"{obj!r} moves (it has a mass or "
                                "density); a pulley is a fixed point: name a static object or "
                                "a frame")
    point = ROPE["point"].read(raw.get("point", [0.0, 0.0, 0.0]), where, f"{key}.point")
    return RopePoint(obj, point)
