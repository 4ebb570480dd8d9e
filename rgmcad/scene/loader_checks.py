"""Checks of the values read from a scenario file.

Each raises :class:`~rgmcad.errors.ScenarioError` naming the file (``where``), the key and
what is allowed. Numbers are checked against :mod:`rgmcad.scene.schema`.
"""

from __future__ import annotations

import math
import os
import re
import stat
from pathlib import Path

import numpy as np

from rgmcad.errors import ScenarioError
from rgmcad.scene.dominoes import overlaps
from rgmcad.scene.schema import MAX_FILE_BYTES, MAX_NAME, MAX_RUN_OVERLAPS, TOUCHING, show

_KINDS = {"str": "a string", "dict": "a table", "list": "a list", "int": "an integer",
          "float": "a number", "bool": "true/false"}


def expect(value, kind, where, key):
    """``value`` if it is of type ``kind`` (a type or a tuple of types; a bool is no number)."""
    kinds = kind if isinstance(kind, tuple) else (kind,)
    if value is None or isinstance(value, bool) and bool not in kinds or not isinstance(value, kinds):
        names = " or ".join(_KINDS[k.__name__] for k in kinds)
        raise ScenarioError(where, key, f"expected {names}, got {show(value)}")
    return value


def key_text(key) -> str:
    """A key read from a file as it can appear in a one-line error (quoted when odd)."""
    if isinstance(key, str) and key and len(key) <= MAX_NAME and all(
            c.isprintable() and not c.isspace() for c in key):
        return key
    return show(key)


def check_keys(table, allowed, where, key):
    """Every key of ``table`` is one of ``allowed``."""
    for k in table:
        if k not in allowed:
            prefix = f"{key}.{key_text(k)}" if key else key_text(k)
            raise ScenarioError(where, prefix, f"unknown key; allowed: {', '.join(allowed)}")


def check_name(name, where, key):
    """A name of an object, run, event or layout: letters, digits, ``_`` and ``-`` (it must
    not read as a body reference, and may name a file)."""
    if (not isinstance(name, str) or not name or len(name) > MAX_NAME
            or not all(c.isalnum() or c in "_-" for c in name)):
        raise ScenarioError(where, key, f"got the name {show(name)}; allowed: 1 to {MAX_NAME} "
                            "letters, digits, '_' or '-' (no '.', '[', ']' or spaces)")


_SCENARIO_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.\-]*")


def check_scenario_name(name, where, key="name", *, from_file=False):
    """A scenario's name: it names output folders (``runs/NAME-sSEED``), so it is a plain name
    of ASCII letters, digits, ``_``, ``-`` and ``.`` (not first), never a path."""
    if (isinstance(name, str) and len(name) <= MAX_NAME
            and _SCENARIO_NAME.fullmatch(name) and ".." not in name):
        return name
    allowed = (f"1 to {MAX_NAME} ASCII letters, digits, '_', '-' or '.' (not first, not "
               "'..'): it names output folders")
    if from_file:
        raise ScenarioError(where, key, f"the file name {show(name)} is no plain name; add "
                            f"name = \"...\" with {allowed}")
    raise ScenarioError(where, key, f"got {show(name)}; allowed: {allowed}")


def one_line(error: ScenarioError) -> ScenarioError:
    """``error`` with any character that would break its one line escaped, and long parts
    cut (an error must stay one line whatever the file held)."""
    def clean(text: str, limit: int) -> str:
        text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
        return text if len(text) <= limit else text[:limit - 3] + "..."

    where, key, message = clean(error.where, 300), clean(error.key, 300), clean(error.message, 600)
    if (where, key, message) == (error.where, error.key, error.message):
        return error
    return type(error)(where, key, message)


def check_overlaps(coords, thickness: float, width: float, where, key) -> None:
    """The standing dominoes of a run (``(n, 3)`` x, y, heading) overlap each other (by more
    than TOUCHING) in at most MAX_RUN_OVERLAPS pairs: the validity check intersects each such
    pair exactly, and a thousand dominoes inside each other would make half a million of
    them (minutes). Fewer overlaps load, and the check reports them as an invalid layout."""
    pairs = overlaps(coords, thickness, width, TOUCHING, enough=MAX_RUN_OVERLAPS)
    if len(pairs[0]) <= MAX_RUN_OVERLAPS:
        return
    i, j, depth = (p[0] for p in pairs)
    gap, n, t, w = float(np.linalg.norm(coords[j, :2] - coords[i, :2])), len(coords), thickness, width
    many = f"more than {MAX_RUN_OVERLAPS:,} pairs of its dominoes overlap, the most a run may have"
    if j == i + 1 and gap < t:
        raise ScenarioError(where, key, f"{many}: dominoes {i} and {j} stand {gap * 1000:.3g} mm "
                            f"apart, less than a domino's thickness ({t * 1000:g} mm); space "
                            f"them at least {t * 1000:g} mm apart ({n:,} dominoes need "
                            f"{(n - 1) * t:.4g} m of path or more)")
    raise ScenarioError(where, key, f"{many} (dominoes {i} and {j} by {depth * 1000:.3g} mm, "
                        f"{gap * 1000:.3g} mm apart): the path turns too tightly for dominoes "
                        f"{w * 1000:g} mm wide, or passes twice through one place; space them "
                        "further apart or widen its curves")


class FileRefused(ValueError):
    """A file :func:`read_limited` does not read: ``str()`` says why, in a few words."""


def read_limited(path: str | Path, limit: int) -> bytes:
    """The bytes of the regular file ``path`` if it holds at most ``limit`` bytes, else
    :class:`FileRefused`. The size is read from the open file (``fstat``) before a byte is
    read, and at most ``limit + 1`` bytes are read: a huge (or sparse) file costs nothing, one
    that grows meanwhile is still cut short, and a FIFO or a device is refused without
    blocking (opened non-blocking). OSError when it cannot be opened or read."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise FileRefused("is a directory")
        if not stat.S_ISREG(info.st_mode):
            raise FileRefused("is not a regular file")
        if info.st_size > limit:
            raise FileRefused(f"the file holds {size_text(info.st_size)}")
        raw = b""
        while len(raw) <= limit and (chunk := os.read(fd, limit + 1 - len(raw))):
            raw += chunk
    finally:
        os.close(fd)
    if len(raw) > limit:
        raise FileRefused(f"the file holds more than {size_text(limit)}")
    return raw


def size_text(n: int) -> str:
    """A count of bytes as people read it: 512 bytes, 3.2 MiB, 50 GiB."""
    for unit, scale in (("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:,} bytes"


def read_text(path: Path, what: str = "scenario file") -> str:
    """The UTF-8 text of a regular file of at most MAX_FILE_BYTES (its size checked before
    it is read: :func:`read_limited`), or one ScenarioError."""
    where = str(path)
    try:
        raw = read_limited(path, MAX_FILE_BYTES)
    except FileRefused as exc:
        size = str(exc) + "; " if str(exc).startswith("the file holds") else ""
        reason = (f"{size}a {what} may hold at most {size_text(MAX_FILE_BYTES)}" if size
                  else f"{exc}; expected a {what}")
        raise ScenarioError(where, "", reason) from None
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        reason = getattr(exc, "strerror", None) or exc
        raise ScenarioError(where, "", f"cannot read the file ({reason})") from None
    try:
        return raw.decode("utf-8").removeprefix("\ufeff")
    except UnicodeDecodeError as exc:
        raise ScenarioError(where, "", f"not UTF-8 text (byte {exc.start:,} cannot be read); "
                            "save the file as UTF-8") from None


_AT = re.compile(r"\(at line (\d+), column \d+\)")
_HEADER = re.compile(r"^\s*\[\[?\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_.\-\"' ]+?)\s*=")


def toml_error(text: str, message: str) -> str:
    """A TOML reader's ``message`` with the key it stopped at, as the file names it
    (``objects.cup.mass``), read from ``text`` at the line the message gives: the reader
    says where, not what (``Cannot overwrite a value (at line 60, column 12)``)."""
    found = _AT.search(message)
    lines = text.splitlines()
    if not found or not 1 <= int(found[1]) <= len(lines):
        return message
    number = int(found[1])
    key = _KEY.match(lines[number - 1])
    if key is None:
        return message
    table = next((h[1] for line in reversed(lines[:number - 1]) if (h := _HEADER.match(line))),
                 None)
    name = key[1].replace(" ", "").replace('"', "").replace("'", "")
    where = f"{found[0][:-1]}: key {(table + '.' if table else '') + name!r})"
    return message[:found.start()] + where + message[found.end():]


def reads_as_radians(low: float, high: float) -> bool:
    """A range of an angle that looks written in radians: narrower than 1.6 degrees (a
    quarter turn in radians), within a turn in radians, not both ends whole degrees."""
    return (high - low < 1.6 and max(abs(low), abs(high)) <= 2 * math.pi
            and not (low.is_integer() and high.is_integer()))
