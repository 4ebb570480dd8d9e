"""Checks of the values read from a scenario file.

Each raises :class:`~rgmcad.errors.ScenarioError` naming the file (``where``), the key and
what is allowed.
"""

from __future__ import annotations

from rgmcad.errors import ScenarioError


def expect(value, kind, where, key):
    """``value`` if it is of type ``kind`` (a type or a tuple of types; a bool is no number)."""
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if value is None or isinstance(value, bool) and bool not in kinds or not isinstance(value, kinds):
        names = " or ".join({"str": "a string", "dict": "a table", "list": "a list",
                             "int": "an integer", "float": "a number", "bool": "true/false"}
                            [k.__name__] for k in kinds)
        raise ScenarioError(where, key, f"expected {names}, got {value!r}")
    return value


def check_keys(table, allowed, where, key):
    """Every key of ``table`` is one of ``allowed``."""
    for k in table:
        if k not in allowed:
            prefix = f"{key}.{k}" if key else k
            raise ScenarioError(where, prefix, f"unknown key; allowed: {', '.join(allowed)}")


def check_name(name, where, key):
    """A name of an object, run or event: it must not read as a body reference."""
    if not name or any(c in name for c in ".[] "):
        raise ScenarioError(where, key, "names cannot contain '.', '[', ']' or spaces")
