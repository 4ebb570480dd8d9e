"""SVG drawings checked before they are parsed: the work of reading one is bounded before it
starts, and the file is cut down to what a run can follow.

An SVG file is XML that the parser (svgelements) expands: ``<use>`` copies what it references
(a copy of a copy of ... grows exponentially, a reference to itself never ends), closing a path
(``z``) looks back along it, a style sheet goes through regular expressions that take time
quadratic in their length. :func:`geometry_of` reads the file's XML once (expat, linear, its
entities bounded first), counts what the parser would do with <use> copies included, refuses
the file in one line naming the limit of :mod:`rgmcad.scene.schema` it passes, and hands the
parser only the elements and attributes of geometry: the containers, paths and references,
their ids, transforms, positions, sizes and view boxes, and ``display``. Text, pictures, style
sheets, scripts, other shapes and an editor's own elements are left out: a run follows a
``<path>``, and style sheets (``<style>``, ``class``) do not move it.
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

from rgmcad.scene.schema import (
    MAX_SVG_BYTES,
    MAX_SVG_CLOSES,
    MAX_SVG_DEPTH,
    MAX_SVG_ELEMENTS,
    MAX_SVG_NUMBERS,
)

SVG = "{http://www.w3.org/2000/svg}"
XLINK_HREF = "{http://www.w3.org/1999/xlink}href"
DROPPED = {"style", "script", "text", "image", "metadata", "title", "desc", "foreignObject",
           "font", "font-face", "rect", "circle", "ellipse", "line", "polyline", "polygon"}
"""SVG elements the parser never gets (their contents neither)."""
KEPT = {"id", "transform", "display", "d", "x", "y", "width", "height", "viewBox",
        "preserveAspectRatio", "href", XLINK_HREF}
"""Attributes the parser gets; every other one (colours, classes, an editor's) is left out."""
LONGEST = 1000
"""Characters of a kept attribute other than ``d`` (an id, a transform, a length)."""
NUMBER = re.compile(r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][-+]?[0-9]+)?")
CLOSE = re.compile(r"[zZ]")
PIECE = re.compile(r"[Mm]")
TRANSFORM = re.compile(r"\s*+(?:(?:matrix|translate|scale|rotate|skewx|skewy)\s*+\([^()]*+\)"
                       r"[\s,]*+)*+", re.IGNORECASE)
_ENTITY = re.compile(rb"<!ENTITY\s+(%\s+)?([^\s%&;<>\"']+)\s+(?:\"([^\"]*)\"|'([^']*)'|"
                     rb"(SYSTEM|PUBLIC)\b)")
_DISPLAY_NONE = re.compile(r"(?:^|;)\s*display\s*:\s*none\s*(?:;|$)", re.IGNORECASE)


def geometry_of(raw: bytes, name: str) -> bytes:
    """The SVG file ``raw`` (at most MAX_SVG_BYTES) cut down to its geometry, for the parser;
    ValueError (one line, naming the file ``name`` and the limit) when reading it would take
    more than the limits allow, or it is no XML."""
    _check_entities(raw, name)
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        raise ValueError(f"{name}: not an SVG file (XML: {exc})") from None
    except RecursionError:  # not expected from expat; kept for a parser that recurses
        raise ValueError(f"{name}: not an SVG file (XML nested too deeply)") from None
    _keep_geometry(root, name)
    _count(root, name)
    return ET.tostring(root)


def _check_entities(raw: bytes, name: str) -> None:
    """Entities declared in the file expand, at most, to MAX_SVG_BYTES (an entity that names
    another entity, or a parameter entity, could expand exponentially: refused)."""
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in raw[:4096]:
        raise ValueError(f"{name}: not UTF-8 text; save the drawing as UTF-8 (plain SVG)")
    if b"<!ENTITY" not in raw:
        return
    found = list(_ENTITY.finditer(raw))
    if len(found) != raw.count(b"<!ENTITY") or any(m[1] or b"&" in (m[3] or m[4] or b"")
                                                    or b"%" in (m[3] or m[4] or b"")
                                                    for m in found):
        raise ValueError(f"{name}: declares XML entities that name other entities or "
                         "parameter entities; save the drawing as plain SVG")
    grows = sum(raw.count(b"&" + m[2] + b";") * len(m[3] or m[4] or b"") for m in found)
    if len(raw) + grows > MAX_SVG_BYTES:
        raise ValueError(f"{name}: its XML entities expand it to more than "
                         f"{MAX_SVG_BYTES // 2**20} MiB (the most a drawing may hold)")


def _local(tag) -> str | None:
    """An element's SVG name (``path``), or None for an element of another namespace (an
    editor's own) or a comment."""
    if not isinstance(tag, str):
        return None
    if tag.startswith(SVG):
        return tag[len(SVG):]
    return None if tag.startswith("{") else tag


def _kept(tag) -> bool:
    """Whether the parser gets an element of this tag (an SVG element not DROPPED)."""
    if not isinstance(tag, str):
        return False  # a comment or a processing instruction
    if tag.startswith("{"):
        return tag.startswith(SVG) and tag[len(SVG):] not in DROPPED
    return tag not in DROPPED


def _keep_geometry(root: ET.Element, name: str) -> None:
    """Remove, in place, every element and attribute the parser need not see (see the
    module); refuse nesting deeper than MAX_SVG_DEPTH before walking further."""
    if _local(root.tag) != "svg":
        raise ValueError(f"{name}: not an SVG file (its root element is not <svg>)")
    stack, count = [(root, 1)], 1
    while stack:
        element, depth = stack.pop()
        if depth > MAX_SVG_DEPTH:
            raise ValueError(f"{name}: elements nested more than {MAX_SVG_DEPTH:,} deep, "
                             "the most a drawing may nest its groups")
        kept = [c for c in element if _kept(c.tag)]
        element[:] = kept  # one slice, not a remove per child (each would scan the rest)
        count += len(kept)
        if count > MAX_SVG_ELEMENTS:
            _too_many_elements(name)
        stack.extend((child, depth + 1) for child in kept)
        style = element.get("style", "")
        attributes = {k: v for k, v in element.attrib.items() if k in KEPT}
        if _DISPLAY_NONE.search(style):
            attributes["display"] = "none"
        for k, v in attributes.items():
            if k != "d" and len(v) > LONGEST:
                raise ValueError(f"{name}: the {k} of a <{_local(element.tag)}> is "
                                 f"{len(v):,} characters long; at most {LONGEST:,}")
            if k == "transform" and not TRANSFORM.fullmatch(v):
                raise ValueError(f"{name}: a transform is not a list of matrix, translate, "
                                 f"scale, rotate, skewX or skewY: {v[:40]!r}")
        element.attrib.clear()
        element.attrib.update(attributes)
        element.text = element.tail = None


def _count(root: ET.Element, name: str) -> None:
    """Refuse a drawing whose elements (every <use> copy counted), numbers of path data and
    transforms, closings of a path, or levels of references pass the schema's limits."""
    ids = {e.get("id"): e for e in root.iter() if e.get("id") is not None}  # the last wins
    own: dict[int, int] = {}
    total = 0
    for element in root.iter():
        d = element.get("d") or ""
        closes = len(CLOSE.findall(d)) if "z" in d or "Z" in d else 0
        if closes > MAX_SVG_CLOSES and max(map(len, map(CLOSE.findall, PIECE.split(d)))) \
                > MAX_SVG_CLOSES:
            raise ValueError(f"{name}: a piece of a path (from one M to the next) is closed "
                             f"(z) more than {MAX_SVG_CLOSES:,} times, the most one piece may "
                             "be: start each closed shape with its own M")
        own[id(element)] = n = closes + _numbers(d + " " + element.get("transform", ""),
                                                 MAX_SVG_NUMBERS - total - closes)
        total += n
        if total > MAX_SVG_NUMBERS:
            _too_many_numbers(name)
    memo: dict[int, tuple[int, int, int]] = {}

    def expanded(element: ET.Element, depth: int) -> tuple[int, int, int]:
        """(elements, numbers, levels) of ``element`` once the parser has copied its <use>s,
        standing ``depth`` levels deep."""
        if id(element) in memo:
            count, numbers, levels = memo[id(element)]
        else:
            if depth > MAX_SVG_DEPTH:  # a <use> of its own ancestor ends here too
                too_deep()
            parts = list(element)
            if _local(element.tag) == "use":
                href = element.get("href", element.get(XLINK_HREF))
                if href is not None and href[1:] in ids:
                    parts.append(ids[href[1:]])
            count, numbers, levels = 1, own[id(element)], 1
            for part in parts:
                c, n, h = expanded(part, depth + 1)
                count, numbers, levels = count + c, numbers + n, max(levels, h + 1)
                if count > MAX_SVG_ELEMENTS:
                    _too_many_elements(name, copies=True)
                if numbers > MAX_SVG_NUMBERS:
                    _too_many_numbers(name, copies=True)
            memo[id(element)] = count, numbers, levels
        if depth - 1 + levels > MAX_SVG_DEPTH:
            too_deep()
        return count, numbers, levels

    def too_deep():
        raise ValueError(f"{name}: groups and <use> references nest more than "
                         f"{MAX_SVG_DEPTH:,} deep, the most a drawing may (or a <use> "
                         "copies itself)")

    expanded(root, 1)


def _numbers(text: str, room: int) -> int:
    """How many numbers ``text`` holds, counted no further than ``room + 1``."""
    n = 0
    for _ in NUMBER.finditer(text):
        n += 1
        if n > room:
            break
    return n


def _too_many_elements(name: str, copies: bool = False):
    how = " (every <use> copy counted)" if copies else ""
    raise ValueError(f"{name}: more than {MAX_SVG_ELEMENTS:,} groups, paths and other "
                     f"elements{how}, the most a drawing may hold")


def _too_many_numbers(name: str, copies: bool = False):
    how = ", every <use> copy counted" if copies else ""
    raise ValueError(f"{name}: its paths and transforms hold more than {MAX_SVG_NUMBERS:,} "
                     f"numbers (coordinates and closings{how}), the most a drawing may hold: "
                     "simplify the drawing, or keep only the path")
