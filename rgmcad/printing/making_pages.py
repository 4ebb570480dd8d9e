"""The template's pages between the parts list and the tiled sheets: the bill of materials
(:mod:`rgmcad.making.bom`) and the numbered assembly steps, each with a picture of the
machine so far (:mod:`rgmcad.making.steps`).

Pages are drawn on the template's :class:`~rgmcad.printing.pdf._Pdf` helper, millimetres
from the top-left; :func:`making_page_count` says how many there are before anything is
drawn, so the tiled sheets can be numbered first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rgmcad.printing.labels import text_width, wrap
from rgmcad.printing.sheets import MARGIN_MM

LINE_MM = 2.6
"""Font size of the bill's lines, mm."""
STEP_MM = 2.3
"""Font size of a step's text, mm."""
STEP_COLUMNS = 2
"""Steps side by side on a page."""
_TOP = MARGIN_MM + 12.0  # below the page's heading
_STEP_TEXT_LINES = 4


@dataclass(frozen=True, eq=False)
class Making:
    """What the making pages show: the ``bill`` (:class:`~rgmcad.making.bom.Bill`, its paper
    and tape lines added by the template), the ``steps`` and one picture per step
    (``pictures``: (h, w, 3) uint8 arrays, all of one size)."""

    bill: object
    steps: tuple = ()
    pictures: tuple = ()

    def to_json(self) -> dict:
        """``scenario``, ``lines`` (the bill's, see :class:`~rgmcad.making.bom.BomLine`) and
        ``steps`` (:class:`~rgmcad.making.steps.Step`)."""
        return {**self.bill.to_json(), "steps": [s.to_json() for s in self.steps]}


def _bill_rows(bill, width: float) -> list[tuple[str, bool]]:
    rows = []
    for text in bill.text_lines():
        head = not text.startswith("  ")
        for i, chunk in enumerate(wrap(text.strip(), LINE_MM, width - 8.0, head)):
            rows.append(((" " * 4 if not head else "") + ("    " if i else "") + chunk, head))
    return rows


def _bill_pages(bill, size_mm) -> list[list[tuple[str, bool]]]:
    w, h = size_mm
    per_page = int((h - _TOP - MARGIN_MM) // (1.3 * LINE_MM))
    rows = _bill_rows(bill, w - 2 * MARGIN_MM)
    return [rows[i:i + per_page] for i in range(0, len(rows), per_page)] or [[]]


def _step_cell(size_mm, picture_aspect: float) -> tuple[float, float, float, int]:
    """``(cell width, picture height, cell height, rows per page)``, mm."""
    w, h = size_mm
    cell_w = (w - 2 * MARGIN_MM - 6.0 * (STEP_COLUMNS - 1)) / STEP_COLUMNS
    pic_h = cell_w * picture_aspect
    cell_h = pic_h + 3.0 + _STEP_TEXT_LINES * 1.25 * STEP_MM + 3.0
    return cell_w, pic_h, cell_h, max(int((h - _TOP - MARGIN_MM) // cell_h), 1)


def _aspect(making: Making) -> float:
    if making.pictures:
        hh, ww = np.asarray(making.pictures[0]).shape[:2]
        return hh / ww
    return 0.75


def making_page_count(making: Making | None, size_mm) -> int:
    """Pages the bill of materials and the steps take on paper of ``size_mm``."""
    if making is None:
        return 0
    rows = _step_cell(size_mm, _aspect(making))[3]
    return len(_bill_pages(making.bill, size_mm)) + math.ceil(
        len(making.steps) / (rows * STEP_COLUMNS))


def draw_making_pages(pdf, making: Making, size_mm, title: str, where=None) -> None:
    """Draw the bill's and the steps' pages; ``where``: body name -> labels of the sheets it
    is drawn on (named after each step)."""
    w, h = size_mm
    where = where or {}
    for i, rows in enumerate(_bill_pages(making.bill, size_mm)):
        pdf.new_page(w, h)
        pdf.text(MARGIN_MM, MARGIN_MM + 5.0, f"{title} - bill of materials"
                 + (" (continued)" if i else ": what to buy or make"), 3.2, bold=True)
        y = _TOP
        for text, head in rows:
            pdf.text(MARGIN_MM, y, text, LINE_MM, bold=head)
            y += 1.3 * LINE_MM
    cell_w, pic_h, cell_h, rows = _step_cell(size_mm, _aspect(making))
    per_page = rows * STEP_COLUMNS
    for k, step in enumerate(making.steps):
        if k % per_page == 0:
            pdf.new_page(w, h)
            pdf.text(MARGIN_MM, MARGIN_MM + 5.0, f"{title} - assembly steps "
                     f"(orange: what the step places; numbers as on the sheets)", 3.2, bold=True)
        slot = k % per_page
        x = MARGIN_MM + (slot % STEP_COLUMNS) * (cell_w + 6.0)
        y = _TOP + (slot // STEP_COLUMNS) * cell_h
        if k < len(making.pictures):
            _picture(pdf, making.pictures[k], x, y, cell_w, pic_h)
        pdf.rect(x, y, cell_w, pic_h, fill=None, stroke=(0.6, 0.6, 0.6), width=0.2)
        sheets = sorted({s for b in step.bodies for s in where.get(b, ())})
        text = step.text + (f" [sheet {', '.join(sheets)}]" if sheets else "")
        label = f"{step.number}."
        pdf.text(x, y + pic_h + 3.5, label, STEP_MM + 0.6, bold=True)
        indent = text_width(label, STEP_MM + 0.6, True) + 1.5
        for j, chunk in enumerate(wrap(text, STEP_MM, cell_w - indent)[:_STEP_TEXT_LINES]):
            pdf.text(x + indent, y + pic_h + 3.5 + j * 1.25 * STEP_MM, chunk, STEP_MM)


def _picture(pdf, picture, x: float, y_down: float, w: float, h: float) -> None:
    from PIL import Image
    from reportlab.lib.utils import ImageReader

    image = ImageReader(Image.fromarray(np.asarray(picture, np.uint8)))
    pdf.c.drawImage(image, x, pdf.y(y_down + h), w, h)


PICTURE_PX = (360, 270)
"""Size of a step's picture, pixels (drawn about 90 mm wide on A4: about 100 dpi)."""


def scene_making(scenario, scene, normal, up, ball_mass=None,
                 size_px: tuple[int, int] = PICTURE_PX, stands=()) -> Making:
    """The :class:`Making` of a posed scene: its bill of materials (``ball_mass``: the
    measurement of :mod:`rgmcad.making.ball_mass`, or None), its assembly steps and their
    pictures seen from the ``normal`` side of the template plane, ``up`` (world directions)
    up; ``stands`` (:mod:`rgmcad.making.stands`) in both, each before the part it holds."""
    from rgmcad.making.bom import bill_of_materials, support_lines
    from rgmcad.making.steps import assembly_steps, render_steps, supports_of

    steps = assembly_steps(scenario, scene, supports_of(stands))
    pictures = render_steps(scenario, scene, steps, normal, up, *size_px, stands=stands)
    return Making(bill_of_materials(scenario, scene, ball_mass=ball_mass,
                                    supports=support_lines(stands)), steps, tuple(pictures))
