"""Markdown helpers of the generated reference pages: table cells that stay cells, and the
check that a hand-written description exists for each key the code knows (and no other)."""

from __future__ import annotations

import re
from collections.abc import Iterable, Mapping


def prose(text) -> str:
    """``text`` with the ``<`` of a would-be HTML tag written as ``&lt;`` (help texts say
    ``<path>``), but not in `code`."""
    parts = str(text).split("`")
    for i in range(0, len(parts), 2):  # the even parts lie outside code spans
        parts[i] = re.sub(r"<(?=[A-Za-z/!?])", "&lt;", parts[i])
    return "`".join(parts)


def cell(text) -> str:
    """``text`` as one markdown table cell: :func:`prose`, on one line, a pipe escaped."""
    parts = prose(str(text).replace("\n", " ")).split("`")
    for i in range(0, len(parts), 2):
        parts[i] = parts[i].replace("|", "\\|")
    return "`".join(parts)


def sentence(text: str) -> str:
    """``text`` with a capital letter and a full stop."""
    text = text.strip()
    return (text[:1].upper() + text[1:] + ("" if text.endswith(".") else ".")) if text else ""


def table(header: Iterable[str], rows: Iterable[Iterable]) -> str:
    """A markdown table; a column empty in every row is left out."""
    header, rows = list(header), [list(r) for r in rows]
    keep = [i for i in range(len(header)) if i == 0 or any(str(r[i]) for r in rows)]
    header, rows = [header[i] for i in keep], [[r[i] for i in keep] for r in rows]
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def code(value) -> str:
    """A default value as the reader would write it (TOML or the command line)."""
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, tuple | list):
        return "`[" + ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in value) + "]`"
    return f"`{value:g}`" if isinstance(value, float) else f"`{value}`"


def rst(text: str) -> str:
    """A docstring's reStructuredText literals (````x````) as markdown code (```x```)."""
    return re.sub(r":\w+:`~?([^`]*)`", r"`\1`", text.replace("``", "`"))


def described(keys: Iterable[str], docs: Mapping[str, str], what: str) -> list[tuple[str, str]]:
    """(key, description) of every key the code accepts; a key without a description, or a
    description of a key the code no longer has, fails the build with the key's name."""
    keys = list(keys)
    missing = [k for k in keys if k not in docs]
    stale = [k for k in docs if k not in keys]
    if missing or stale:
        raise ValueError(f"reference of {what}: describe {missing} and drop {stale} "
                         "(rgmcad/reference)")
    return [(k, docs[k]) for k in keys]
