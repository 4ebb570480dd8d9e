"""``reference/parts.md``: every shipped part family and its parameters, read from the family
files (imported, never built: no CAD runs) and their source (each field's comment)."""

from __future__ import annotations

import ast
import dataclasses
import io
import tokenize
from pathlib import Path

from rgmcad.parts.family import FINEST, FLOAT_RANGE, INT_RANGE, Family, load_families
from rgmcad.reference.text import cell, code, prose, rst, table


def field_notes(source: Path) -> dict[str, tuple[str, str]]:
    """{field: (annotation, comment)} of the ``Params`` class of a family file, as written."""
    text = source.read_text()
    comments = {t.start[0]: t.string.lstrip("# ").strip()
                for t in tokenize.generate_tokens(io.StringIO(text).readline)
                if t.type == tokenize.COMMENT}
    notes = {}
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.ClassDef) and node.name == "Params":
            for item in node.body:
                if isinstance(item, ast.AnnAssign) and isinstance(item.target, ast.Name):
                    notes[item.target.id] = (ast.unparse(item.annotation),
                                             comments.get(item.lineno, ""))
    return notes


def checks(source: Path) -> list[str]:
    """The messages ``Params.check`` of a family file returns (the rules it refuses to break),
    plain strings only."""
    found = []
    for node in ast.walk(ast.parse(source.read_text())):
        if isinstance(node, ast.FunctionDef) and node.name == "check":
            for ret in (n for n in ast.walk(node) if isinstance(n, ast.Return) and n.value):
                if isinstance(ret.value, ast.JoinedStr):  # an f-string: no fixed text
                    continue
                parts = [ret.value, *ast.iter_child_nodes(ret.value)]  # a ``x if y else z``
                found += [c.value for c in parts
                          if isinstance(c, ast.Constant) and isinstance(c.value, str)]
    return found


def _allowed(kind: str, metadata) -> str:
    """What the loader accepts for a field (:func:`rgmcad.parts.family._coerce`)."""
    if kind not in ("float", "int") and not kind.startswith("float |"):
        return ""
    integer = kind == "int"
    low, high = metadata.get("range") or (INT_RANGE if integer else FLOAT_RANGE)
    unit = "" if integer else metadata.get("unit", "m")
    text = f"{'an integer' if integer else 'a number'}{f' ({unit})' if unit else ''}, " \
           f"{low:g} to {high:g}"
    if unit == "m":
        text += f"; 0 or at least {FINEST:g} m in size"
    return text


def family_section(family: Family) -> str:
    doc, notes, rules = "", {}, []
    if family.source is not None:
        doc = ast.get_docstring(ast.parse(family.source.read_text())) or ""
        notes, rules = field_notes(family.source), checks(family.source)
    rows = []
    for f in dataclasses.fields(family.params):
        kind, comment = notes.get(f.name, (getattr(f.type, "__name__", str(f.type)), ""))
        default = ("needed" if f.default is dataclasses.MISSING
                   and f.default_factory is dataclasses.MISSING
                   else "see note" if f.default is None else code(f.default))
        rows.append((f"`{f.name}`", _allowed(kind, f.metadata), default, comment))
    out = [f"## `{family.name}` {{#{family.name}}}", "", cell(family.description), ""]
    out += [p for para in doc.split("\n\n")[1:] for p in (prose(rst(para)), "")]
    out += [table(["parameter", "read as", "default", "note"], rows) if rows
            else "No parameters.", ""]
    if rules:
        out += ["It refuses parameters that break these rules:", "",
                *(f"* {prose(r)}" for r in rules), ""]
    return "\n".join(out)


def page(families: dict[str, Family] | None = None) -> str:
    families = load_families() if families is None else families
    return "\n".join([
        "# Part families", "",
        "The part families that ship with rgmcad. A scenario names one with `part = \"NAME\"` "
        "and gives its parameters with `params = { ... }`; a parameter with a default may be "
        "left out. Each family is one Python file in the shipped `parts/` folder, its shape "
        "drawn with CadQuery; `rgmcad --parts DIR` uses another folder of them instead. "
        "Lengths are in metres. Each parameter is first read as the table says, then the "
        "family checks its own rules, and `rgmcad check` names the one a file breaks.", "",
        table(["family", "what it is"],
              [(f"[`{name}`](#{name})", f.description)
               for name, f in families.items()]), "",
        *(family_section(f) for f in families.values())])
