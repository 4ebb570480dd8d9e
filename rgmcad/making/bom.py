"""The bill of materials of a layout: what to buy or make to build it.

Each part of the scene is counted once, on one line of its kind:

* ``ball``: balls by diameter and the mass the simulation assumed (buy them: marbles, steel
  or wooden balls), with how far off a ball's mass may be before the built-by-hand figure
  drops, where that was measured (:mod:`rgmcad.making.ball_mass`);
* ``domino``: the dominoes of the runs, by size and mass;
* ``printed``: parts of the other families, 3D-printed from their CAD meshes (one STL file
  per distinct part, :func:`write_stls`);
* ``cut``: boxes (blocks, planks, walls), cut from card, foam board or wood, by size;
* ``support``: the stands that hold raised parts, once given (:class:`BomLine` from
  :mod:`rgmcad.making.supports`);
* ``rope``: each rope by the length to cut;
* ``paper`` and ``tape``: the template's sheets, and tape for its seams (:class:`PaperUse`).

Sizes are millimetres (the part's bounding box in its own frame), masses grams.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

KINDS = ("ball", "domino", "printed", "cut", "support", "rope", "paper", "tape")
"""Kinds of line, in the order the bill lists them."""

MADE = {"ball": "ball", "box": "cut", "plane": None, "frame": None}
"""How a part family is made when it is not a domino of a run: ``"ball"`` (bought),
``"cut"`` or None (nothing to make: infinite planes, frames); any other family, a user's
included, is ``"printed"``."""

TAPE_PER_MARK_MM = 40.0
"""Length of the strip of tape laid across a seam at each pair of matching marks, mm."""


@dataclass(frozen=True)
class BomLine:
    """One line of the bill.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    what : str
        What it is, for a person (``"ball, 20.0 mm across"``).
    count : int
        How many (pieces; sheets for paper, strips for tape).
    parts : tuple of str
        The scene's objects (or ropes, supports) the line covers, one per piece.
    size_mm : tuple of float
        Bounding-box size, mm (a ball: its diameter; a rope: its cut length).
    mass_g : float or None
        Mass of one, as simulated, grams (None: static, or not a part).
    note : str
        More for a person (the mass a ball may have, the file to print).
    files : tuple of str
        Files to make it from (STL), relative to the template folder.
    """

    kind: str
    what: str
    count: int
    parts: tuple[str, ...] = ()
    size_mm: tuple[float, ...] = ()
    mass_g: float | None = None
    note: str = ""
    files: tuple[str, ...] = ()

    def to_json(self) -> dict:
        return {"kind": self.kind, "what": self.what, "count": self.count,
                "parts": list(self.parts), "size_mm": list(self.size_mm),
                "mass_g": self.mass_g, "note": self.note, "files": list(self.files)}

    def text(self) -> str:
        """``"3 x ball, 20.0 mm across, 10.0 g: ..."``."""
        note = f"; {self.note}" if self.note else ""
        return f"{self.count} x {self.what}{note}"


@dataclass(frozen=True)
class PaperUse:
    """What a printed template takes: ``pages`` sheets of ``paper``, ``tiled`` of them laid
    out, and ``marks`` pairs of matching marks on ``seams`` seams."""

    paper: str
    pages: int
    tiled: int
    seams: int
    marks: int


@dataclass(frozen=True)
class Bill:
    """The bill of materials of one layout: ``lines`` in the order of :data:`KINDS`."""

    scenario: str
    lines: tuple[BomLine, ...] = field(default_factory=tuple)

    def of(self, kind: str) -> list[BomLine]:
        return [line for line in self.lines if line.kind == kind]

    def to_json(self) -> dict:
        return {"scenario": self.scenario, "lines": [line.to_json() for line in self.lines]}

    def text_lines(self) -> list[str]:
        """One line per :class:`BomLine`, under a heading per kind."""
        heads = {"ball": "Balls (buy)", "domino": "Dominoes", "printed": "3D-printed parts",
                 "cut": "Cut parts (card, foam board or wood)", "support": "Supports",
                 "rope": "Ropes", "paper": "Paper", "tape": "Tape"}
        out = []
        for kind in KINDS:
            lines = self.of(kind)
            if lines:
                out.append(heads[kind])
                out += [f"  {line.text()}" for line in lines]
        return out

    def with_paper(self, use: PaperUse) -> Bill:
        """This bill with its paper and tape lines for the template ``use`` (replacing any)."""
        strips = use.marks + 4  # and one at each corner of the laid-out template
        extra = [BomLine("paper", f"sheet of {use.paper.upper()} paper", use.pages,
                         note=f"{use.tiled} laid out as the template, the rest to read; print "
                         "at 100 % / actual size"),
                 BomLine("tape", f"strip of tape, about {TAPE_PER_MARK_MM:.0f} mm", strips,
                         note=f"across the {use.seams} seams at their matching marks, and the "
                         "template's corners to the table")]
        kept = [line for line in self.lines if line.kind not in ("paper", "tape")]
        return replace(self, lines=_sorted([*kept, *extra]))


def _sorted(lines) -> tuple[BomLine, ...]:
    return tuple(sorted(lines, key=lambda line: KINDS.index(line.kind)))


def _mm(v: float) -> str:
    """A length, mm, to 0.1 without trailing zeros."""
    return f"{v:.1f}".rstrip("0").rstrip(".")


def _size(sizes: Sequence[float]) -> str:
    return " x ".join(_mm(s) for s in sizes) + " mm"


def _grams(body) -> float | None:
    return None if body.static else round(float(body.mass) * 1000.0, 1)


def _bbox_mm(body) -> tuple[float, ...]:
    lo, hi = np.asarray(body.built.bbox, float)
    return tuple(round(float(v) * 1000.0, 1) for v in hi - lo)


def bill_of_materials(scenario, scene, *, supports: Sequence[BomLine] = (),
                      ball_mass: Mapping | None = None, paper: PaperUse | None = None) -> Bill:
    """The bill of a posed ``scene`` of ``scenario``.

    ``supports``: lines of the supports that hold raised parts (their ``parts`` name the
    supports); ``ball_mass``: what :func:`rgmcad.making.ball_mass.measure_ball_mass` found
    for this layout (None: not measured, and the note says how to); ``paper``: the
    template's sheets, for the paper and tape lines.
    """
    runs = {name for names in scenario.runs.values() for name in names}
    groups: dict[tuple, list[str]] = {}
    for obj in scenario.body_objects():
        kind = "domino" if obj.name in runs else MADE.get(obj.part, "printed")
        main = scene.bodies.get(obj.name)
        if kind is None or main is None or main.plane:
            continue
        sizes = _bbox_mm(main)
        if kind == "ball":
            sizes = (max(sizes),)
        params = repr(obj.params) if kind == "printed" else ""
        key = (kind, obj.part, sizes, _grams(main), params)
        groups.setdefault(key, []).append(obj.name)
    lines = []
    printed: dict[str, int] = {}
    for (kind, family, sizes, grams, _), names in groups.items():
        mass = "" if grams is None else f", {_mm(grams)} g"
        if kind == "ball":
            what = f"ball, {_mm(sizes[0])} mm across{mass}"
            lines.append(BomLine(kind, what, len(names), tuple(names), sizes, grams,
                                 _ball_note(ball_mass, grams)))
        elif kind == "domino":
            lines.append(BomLine(kind, f"domino {_size(sorted(sizes))}{mass}", len(names),
                                 tuple(names), tuple(sorted(sizes)), grams,
                                 "wooden or plastic, of this size and mass"))
        elif kind == "cut":
            fixed = "fixed" if grams is None else "moving: match the mass"
            lines.append(BomLine(kind, f"block {_size(sizes)}{mass} ({fixed})", len(names),
                                 tuple(names), sizes, grams, ", ".join(names)))
        else:
            printed[family] = printed.get(family, 0) + 1
            files = tuple(stl_names(family, printed[family], scene.bodies, names[0]))
            weigh = "" if grams is None else "moving: print it to this mass (infill); "
            lines.append(BomLine(kind, f"{family} {_size(sizes)}{mass}", len(names),
                                 tuple(names), sizes, grams, weigh + ", ".join(names), files))
    for rope in scene.ropes:
        cut = round(float(rope.length) * 1000.0)
        lines.append(BomLine("rope", f"rope {rope.name}, {cut} mm long plus the knots", 1,
                             (rope.name,), (float(cut),), None,
                             f"path {_mm(float(rope.initial_length) * 1000.0)} mm at the start; "
                             "thin, not stretchy"))
    lines += list(supports)
    bill = Bill(scenario.name, _sorted(lines))
    return bill.with_paper(paper) if paper is not None else bill


def support_lines(stands) -> list[BomLine]:
    """A ``support`` line per stand of :mod:`rgmcad.making.stands`: its base, its height and
    the part it holds; printed from ``LABEL.stl`` or folded from card (``LABEL-card.svg``),
    as ``rgmcad supports`` writes them."""
    out = []
    for s in stands:
        length, width = (v * 1000.0 for v in s.size)
        h = np.asarray(s.heights(), float) * 1000.0
        high = _mm(h.max()) if abs(h.max() - h.min()) < 0.05 else f"{_mm(h.min())} to {_mm(h.max())}"
        out.append(BomLine("support", f"stand {s.label}, {_mm(length)} x {_mm(width)} mm, "
                           f"{high} mm high", 1, (s.label,), (round(length, 1), round(width, 1),
                                                             round(float(h.max()), 1)),
                           None, f"under {s.part}; print {s.label}.stl or fold "
                           f"{s.label}-card.svg from card",
                           (f"{s.label}.stl", f"{s.label}-card.svg")))
    return out


def _ball_note(measured: Mapping | None, grams: float | None) -> str:
    if grams is None:
        return "fixed in place"
    if not measured:
        return ("how far its mass may be off was not measured (tools/ball_mass.py measures "
                "it for a run's layout)")
    low, high = measured["kept"]
    base = measured["rates"][measured["factors"].index(1.0)]
    return (f"a ball of {_mm(grams * low)} to {_mm(grams * high)} g keeps the built-by-hand "
            f"figure ({base['rate'] * 100:.0f} % at {_mm(grams)} g; "
            f"{measured['samples']} builds at each of {len(measured['factors'])} masses)")


def stl_names(family: str, index: int, bodies, obj: str) -> list[str]:
    """File names of the STLs of object ``obj``'s bodies: ``print/FAMILY-INDEX.stl``, then
    ``print/FAMILY-INDEX-KEY.stl`` for its other bodies (a lever's axle)."""
    out = []
    for name, body in bodies.items():
        if body.object == obj and not body.plane:
            key = name.partition(".")[2]
            out.append(f"print/{family}-{index}{'-' + key if key else ''}.stl")
    return out


def write_stls(bill: Bill, scene, folder: str | Path) -> list[Path]:
    """Write the STL of every printed part of ``bill`` under ``folder`` (millimetres, as
    slicers read STL): the mesh of the line's first part, each body in its part frame."""
    import trimesh

    folder = Path(folder)
    written = []
    for line in bill.of("printed"):
        bodies = [b for b in scene.bodies.values() if b.object == line.parts[0] and not b.plane]
        for body, name in zip(bodies, line.files, strict=True):
            path = folder / name
            path.parent.mkdir(parents=True, exist_ok=True)
            mesh = trimesh.Trimesh(np.asarray(body.built.vertices, float) * 1000.0,
                                   np.asarray(body.built.faces), process=False)
            mesh.export(path)
            written.append(path)
    return written
