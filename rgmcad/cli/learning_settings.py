"""``--set KEY=VALUE`` of ``optimize`` and ``benchmark``: a learning setting changed from the
budget's, read as the type of its field of :class:`~rgmcad.learning.settings.LearningSettings`
and checked by it."""

from __future__ import annotations

import argparse
import math

__all__ = ["add_set_arg", "changes_of", "setting_changes"]

# settings with flags of their own: one way to ask for each, one directory name for each
_OWN_FLAGS = {"exploration_batch": "--batch", "factorized": "--full",
              "centering": "--centering", "n_jobs": "--workers"}
_TRUE, _FALSE = ("true", "yes", "on", "1"), ("false", "no", "off", "0")


def add_set_arg(p: argparse.ArgumentParser, where: str) -> None:
    p.add_argument("--set", action="append", default=[], dest="changes", metavar="KEY=VALUE",
                   help="change one learning setting from the budget's (repeatable), e.g. "
                   "second_look_rounds=3, close_in_copies=16, verify_samples=512, "
                   "svm_C_grid=0.1,1,10; every setting, its default and why: "
                   f"rgmcad/learning/settings.py; {where}")


def changes_of(args) -> dict:
    """``optimize``'s ``--set`` flags, checked with its budget and its other flags."""
    flags = {"centering": args.centering, "factorized": False if args.full else None,
             "exploration_batch": args.batch}
    return setting_changes(args.changes, args.budget,
                           {k: v for k, v in flags.items() if v is not None})


def setting_changes(pairs: list[str], budget: str, flags: dict | None = None) -> dict:
    """``{field: value}`` of ``--set KEY=VALUE`` flags, each value read as its field's type;
    a malformed pair, an unknown or repeated key, a value of the wrong type or one the
    settings refuse (``budget``'s settings with ``flags``, the settings other flags change):
    :class:`~rgmcad.errors.UsageError`."""
    import typing

    from rgmcad.errors import UsageError
    from rgmcad.learning.settings import LearningSettings
    from rgmcad.learning.settings import budget as budget_settings

    types = typing.get_type_hints(LearningSettings)
    changes: dict = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise UsageError("--set", pair, "expected KEY=VALUE, e.g. second_look_rounds=3")
        if key in _OWN_FLAGS:
            raise UsageError("--set", key, f"has a flag of its own: use {_OWN_FLAGS[key]}")
        if key not in types:
            names = sorted(set(types) - set(_OWN_FLAGS))
            raise UsageError("--set", key, f"not a learning setting; one of: {', '.join(names)}")
        if key in changes:
            raise UsageError("--set", key, "given twice")
        changes[key] = _read(text.strip(), types[key], key)
    try:
        budget_settings(budget).replace(**(flags or {}), **changes)
    except (ValueError, TypeError) as exc:  # the settings' own checks, in their words
        text = str(exc)  # the key it names first, else one it mentions
        key = min(changes, key=lambda k: (f"LearningSettings.{k} " not in text, k not in text))
        message = text.replace(f"LearningSettings.{key} ", "").replace("LearningSettings.", "")
        raise UsageError("--set", key, message) from None
    return changes


def _read(text: str, kind, key: str):
    """``text`` as a value of the type ``kind`` (int, float, bool, a Literal, a tuple)."""
    import typing

    from rgmcad.errors import UsageError

    origin, args = typing.get_origin(kind), typing.get_args(kind)
    if origin is typing.Literal:
        if text not in args:
            raise UsageError("--set", key, f"expected one of {', '.join(args)}, got {text!r}")
        return text
    if origin is tuple:
        items = [t.strip() for t in text.split(",")]
        if not text or not all(items):
            raise UsageError("--set", key, "expected comma-separated values, e.g. 0.1,1,10")
        if args[0] is float:
            return tuple(_read(t, float, key) for t in items)
        return tuple(None if t.lower() == "none" else t for t in items)
    if kind is bool:
        if text.lower() not in _TRUE + _FALSE:
            raise UsageError("--set", key, f"expected true or false, got {text!r}")
        return text.lower() in _TRUE
    try:
        value = kind(text)
    except ValueError:
        what = "a whole number" if kind is int else "a number"
        raise UsageError("--set", key, f"expected {what}, got {text!r}") from None
    if isinstance(value, float) and not math.isfinite(value):
        raise UsageError("--set", key, f"expected a finite number, got {text!r}")
    return value
