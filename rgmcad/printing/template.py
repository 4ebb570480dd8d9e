"""Printable 1:1 assembly templates of a posed layout, tiled over sheets of paper.

A layout's parts are projected on one plane (:mod:`~rgmcad.printing.plane`: the floor they
stand on, the board they are pinned to, or an axis plane) and drawn at true scale
(:mod:`~rgmcad.printing.drawing`, :mod:`~rgmcad.printing.labels`): each part's exact
silhouette, its placement order and name, its height above the plane, the tilt the outline
cannot show, and its tolerances. The drawing is cut into sheets that meet on seam lines with
matching marks (:mod:`~rgmcad.printing.tiling`, :mod:`~rgmcad.printing.seams`), each sheet
carrying its label, a 100 mm scale bar,
"print at 100 %" and four AprilTag 36h11 marks (:mod:`~rgmcad.printing.sheets`) from which
:func:`rgmcad.printing.check.verify_print` recognises the sheet and measures the printer's
scale. The first page holds an assembly map, test squares (100 mm and 1 in), the parts list
and a legend (:mod:`~rgmcad.printing.pdf`). The same drawing is written as one SVG at 1:1
in millimetres (:mod:`~rgmcad.printing.svg`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from pathlib import Path

from shapely.ops import unary_union

from rgmcad.errors import RgmcadError, ScenarioError
from rgmcad.making.bom import PaperUse, write_stls
from rgmcad.printing.drawing import PartOutline, build_drawing
from rgmcad.printing.inputs import template_inputs, with_supports
from rgmcad.printing.making_pages import Making, making_page_count, scene_making
from rgmcad.printing.pdf import cover_page_count, empty_sheets, write_pdf
from rgmcad.printing.plane import PlaneFrame, resolve_plane
from rgmcad.printing.ropes import scene_ropes
from rgmcad.printing.seams import label_keepouts, seams_of
from rgmcad.printing.sheets import MAP_SLOT, SheetInfo, sheet_info
from rgmcad.printing.svg import write_svg
from rgmcad.printing.tiling import choose_paper, tile_sheets

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())


@dataclass(frozen=True, eq=False)
class TemplateResult:
    """What :func:`make_template` wrote.

    Attributes
    ----------
    pdf, svg : Path
        The files.
    plane : str
        Kind of plane used: ``"floor"``, ``"board"``, ``"xy"``, ``"xz"``, ``"yz"``, ``"plane"``.
    frame : PlaneFrame
        The plane's frame (world <-> drawing mm).
    paper, orientation : str
    grid : (int, int)
        ``(cols, rows)`` of tiled sheets.
    sheet_labels : tuple of str
        Labels of the tiled sheets in page order (row by row).
    sheets : tuple of SheetInfo
        The tiled sheets, in page order.
    map_sheet : SheetInfo
        The first page.
    tag_centres : dict
        ``{label: {tag_id: (x, y)}}`` planned mark centres per page (``"map"`` included),
        sheet mm.
    parts : tuple of PartOutline
        In placement order.
    extent_mm : (float, float, float, float)
        ``(u0, v0, u1, v1)`` of the whole drawing, drawing mm; the SVG's viewBox is
        ``0 0 (u1 - u0) (v1 - v0)`` with SVG ``x = u - u0`` and ``y = v1 - v``.
    overlap_mm : float
        Width of the strips neighbouring sheets share, mm.
    n_pages : int
        Pages in the PDF: the first page, parts-list continuation pages, the sheets.
    frames : tuple of FrameNote
        Frames whose tolerances are marked at their origin.
    ropes : tuple of RopeOutline
        The ropes as drawn (their paths, drawing mm), in the order given.
    empty_sheets : tuple of str
        Labels of the sheets that show no part and no rope (each says so, and the map
        greys it).
    making : Making or None
        The bill of materials (its paper and tape lines for this template) and the assembly
        steps, on the pages after the parts list.
    """

    pdf: Path
    svg: Path
    plane: str
    frame: PlaneFrame
    paper: str
    orientation: str
    grid: tuple[int, int]
    sheet_labels: tuple[str, ...]
    sheets: tuple[SheetInfo, ...]
    map_sheet: SheetInfo
    tag_centres: dict
    parts: tuple[PartOutline, ...]
    extent_mm: tuple[float, float, float, float]
    overlap_mm: float
    n_pages: int = 0
    frames: tuple = ()
    ropes: tuple = ()
    empty_sheets: tuple[str, ...] = ()
    making: Making | None = None


def make_template(parts, base_planes, out_dir, *, plane: str | None = None,
                  paper: str | None = None, orientation: str | None = None,
                  overlap_mm: float = 12.0, title: str = "", frames=(), ropes=(),
                  note: str = "", making: Making | None = None) -> TemplateResult:
    """Write a printable 1:1 tiled assembly template of a posed layout.

    Parameters
    ----------
    parts : sequence of PlacedPart
        Posed parts (world metres).
    base_planes : sequence of BasePlane
        The scenario's infinite planes; never drawn, but the template plane may be one.
    out_dir : str or Path
        Folder for ``template.pdf`` and ``template.svg`` (created if missing).
    plane : str, optional
        ``"floor"``, ``"board"``, ``"xy"``, ``"xz"``, ``"yz"`` or a base plane's name; see
        :func:`rgmcad.printing.plane.resolve_plane` (None chooses).
    paper : str, optional
        ``"a4"``, ``"letter"`` or ``"a3"``; None picks the one that needs the fewest sheets
        (ties go to a4, then letter).
    orientation : str, optional
        ``"portrait"`` or ``"landscape"``; None picks the one with fewer sheets (ties:
        portrait).
    overlap_mm : float
        Width of the strips neighbouring sheets share, mm.
    title : str
        Printed on every page.
    frames : sequence of FrameNote
        Frames whose tolerances are stated once, at their origin.
    ropes : sequence of PlacedRope
        Ropes drawn along their paths and listed with the length to cut.
    making : Making, optional
        The bill of materials and the assembly steps, drawn after the parts list; the bill
        gets the template's paper and tape.

    Returns
    -------
    TemplateResult

    Raises
    ------
    ValueError
        No parts, an unknown plane or paper, an overlap out of range, a part that projects
        to nothing, or a drawing that needs more than 12 x 12 sheets.
    """
    parts = sorted(parts, key=lambda p: (p.order, p.name))
    if not parts:
        raise ValueError("no parts to draw")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    title = title or "rgmcad layout"
    frame = resolve_plane(parts, base_planes, plane)
    drawing, outlines = build_drawing(parts, base_planes, frame, frames=frames, ropes=ropes)
    u0, v0, u1, v1 = drawing.extent
    width, height = u1 - u0, v1 - v0
    paper, orientation, cols, rows = choose_paper(width, height, paper, orientation,
                                                  overlap_mm)
    log.info("template: plane %s, %s %s, %d x %d sheets, drawing %.0f x %.0f mm",
             frame.kind, paper, orientation, cols, rows, width, height)

    # pages: the first page (and parts-list continuation pages), then sheets row by row
    map_info = sheet_info("map", -1, -1, 1, paper, "portrait", MAP_SLOT)
    # the sheets cover the first drawing; its labels are then placed again, clear of the
    # seams and inside what the sheets keep
    tiled = drawing.extent
    sheets = tile_sheets(tiled, paper, orientation, (cols, rows), overlap_mm, 2)  # renumbered below
    # the parts, which seam marks and tick labels keep off (a millimetre around each)
    clear = unary_union([o.outline for o in outlines]).buffer(1.0)
    seams = seams_of(sheets, clear)
    if len(sheets) > 1:
        avoid, inside = label_keepouts(sheets, seams)
        drawing, outlines = build_drawing(parts, base_planes, frame, avoid=avoid, inside=inside,
                                          geoms=[o.outline for o in outlines], frames=frames,
                                          ropes=ropes)
    # the parts list names each part's sheets, and its length numbers the sheets' pages
    first = (cover_page_count(outlines, map_info.size_mm, sheets, drawing.ropes)
             + making_page_count(making, map_info.size_mm) + 1)
    sheets = tuple(replace(s, page=first + i) for i, s in enumerate(sheets))
    if making is not None:
        use = PaperUse(paper, first - 1 + len(sheets), len(sheets), len(seams),
                       sum(len(s.marks) for s in seams))
        making = replace(making, bill=making.bill.with_paper(use))
    pdf_path, svg_path = out_dir / "template.pdf", out_dir / "template.svg"
    empty = empty_sheets(outlines, sheets, drawing.ropes)
    n_pages = write_pdf(pdf_path, title, drawing, outlines, frame, map_info, sheets,
                        (cols, rows), paper, orientation, overlap_mm, empty, note, seams, clear,
                        making)
    write_svg(svg_path, drawing, title, frame)

    centres = {"map": dict(map_info.tag_centres_mm)}
    centres.update({s.label: dict(s.tag_centres_mm) for s in sheets})
    return TemplateResult(
        pdf=pdf_path, svg=svg_path, plane=frame.kind, frame=frame, paper=paper,
        orientation=orientation, grid=(cols, rows), sheet_labels=tuple(s.label for s in sheets),
        sheets=sheets, map_sheet=map_info, tag_centres=centres, parts=outlines,
        extent_mm=drawing.extent, overlap_mm=float(overlap_mm), n_pages=n_pages,
        frames=tuple(frames), ropes=drawing.ropes,
        empty_sheets=tuple(s.label for s in sheets if s.label in empty), making=making,
    )


def scene_template(scenario, scene, out_dir, *, tolerances=None, plane: str | None = None,
                   paper: str | None = None, overlap_mm: float = 12.0,
                   title: str = "", note: str = "", push=None, making: bool = True,
                   ball_mass=None, supports=()) -> TemplateResult:
    """:func:`make_template` of a posed scene of ``scenario``, parts in placement order, with
    its ropes.

    ``tolerances`` (``{"object.component": (down, up)}``, metres or degrees) are printed
    beside the parts (see :mod:`rgmcad.printing.inputs`), as pushes against a part where
    ``push`` (``{"object.component": {"low" | "high": part}}``) says so. A plane the scenario lacks, an
    overlap out of range or a drawing too big for the paper raise :class:`ScenarioError`
    naming the scenario file. With ``making``, the PDF also holds the bill of materials
    (``ball_mass``: :func:`rgmcad.making.ball_mass.read_cached`'s measurement, or None) and
    the assembly steps with their pictures, and the printed parts' STL files are written to
    ``out_dir/print/``. ``supports`` (stands of :mod:`rgmcad.making.stands`) are drawn as
    parts placed first: their footprints, labels and sizes.
    """
    parts, planes, frames = template_inputs(scenario, scene, tolerances, push)
    parts = with_supports(parts, supports)
    try:
        made = None
        if making:
            frame = resolve_plane(parts, planes, plane)
            made = scene_making(scenario, scene, frame.normal, frame.v_axis, ball_mass,
                                stands=supports)  # in the bill, and a step before each part
        result = make_template(parts, planes, out_dir, plane=plane, paper=paper,
                               overlap_mm=overlap_mm, title=title, frames=frames,
                               ropes=scene_ropes(scene), note=note, making=made)
        if made is not None:
            write_stls(made.bill, scene, out_dir)
        return result
    except RgmcadError:
        raise
    except ValueError as exc:
        raise ScenarioError(str(scenario.path), "template", str(exc)) from None


@dataclass(frozen=True)
class LayoutNotes:
    """What a layout file written by the optimiser adds to its template: the printed
    tolerances, the cover's note on building by hand, the sides to push against, and the ball
    mass measurement kept beside it (:func:`layout_notes`)."""

    tolerances: dict
    note: str = ""
    push: dict | None = None
    ball_mass: dict | None = None


def layout_notes(scenario, scenario_path, layout: str | None, values, *, by_value: bool = False
                 ) -> LayoutNotes:
    """The :class:`LayoutNotes` of ``layout`` (a layout file of a run; a named layout, none or
    one changed with ``--value`` (``by_value``) carries nothing), for ``rgmcad template`` and
    ``rgmcad supports`` alike."""
    from rgmcad.making.ball_mass import read_cached
    from rgmcad.scene.layout_files import read_hand_note, read_push_against, read_tolerances

    if not layout or layout in scenario.layouts or by_value:
        return LayoutNotes({})
    path = Path(layout)
    return LayoutNotes(read_tolerances(scenario, path), read_hand_note(path),
                       read_push_against(scenario, path),
                       read_cached(path.parent, scenario_path, values))
