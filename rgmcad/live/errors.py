"""Errors as the live page shows them: the one line the command line prints, and the line of
the scenario file it is about where that can be found."""

from __future__ import annotations

import re

from rgmcad.errors import RgmcadError

__all__ = ["failure_line", "file_line", "key_line"]

_AT_LINE = re.compile(r"\(at line (\d+), column \d+")
_HEADER = re.compile(r"^\s*\[\[?\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_INDEX = re.compile(r"\[-?\d+\]$")


def failure_line(exc: BaseException) -> str:
    """One line for an unexpected exception (a simulation that raised)."""
    text = " ".join(str(exc).split()) or "no message"
    return f"rgmcad: error: the simulation failed: {type(exc).__name__}: {text[:300]}"


def _unquoted(key: str) -> str:
    return key.replace(" ", "").replace('"', "").replace("'", "")


def key_line(text: str, key: str) -> int | None:
    """The line (1-based) of ``text`` (TOML) where the dotted ``key`` of an error is written
    (``objects.track.free.x``): the table header that holds the longest part of it, then the
    next part's line within that table; None when not found."""
    parts = [_INDEX.sub("", p) for p in key.split(".") if p]
    lines = text.splitlines()
    headers = [(i, _unquoted(m[1])) for i, line in enumerate(lines) if (m := _HEADER.match(line))]
    start, rest = -1, parts
    for k in range(len(parts), 0, -1):
        found = next((i for i, name in headers if name == ".".join(parts[:k])), None)
        if found is not None:
            start, rest = found, parts[k:]
            break
    if not rest:
        return start + 1 if start >= 0 else None
    end = next((i for i, _ in headers if i > start), len(lines))
    word = re.compile(rf"^\s*[\"']?{re.escape(rest[0])}[\"']?\s*[=.]")
    for i in range(start + 1, end):
        if word.match(lines[i]):
            return i + 1
    return start + 1 if start >= 0 else None


def file_line(exc: RgmcadError, path: str, text: str | None) -> int | None:
    """The line of the scenario file ``path`` (its ``text``) that ``exc`` is about, if it is
    about that file and the line can be told."""
    if text is None or exc.where != str(path):
        return None
    at = _AT_LINE.search(exc.message)
    if at:
        return int(at[1])
    return key_line(text, exc.key) if exc.key else None
