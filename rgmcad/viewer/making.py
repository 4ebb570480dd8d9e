"""The bill of materials and the assembly steps of a run's layout, for its reports: a section
of ``report.html`` (the steps' pictures inline) and lines of ``report.md`` (the steps' text;
their pictures are in the page). Nothing is written to the run directory.

The same bill (:mod:`rgmcad.making.bom`, without the template's paper and tape, which the
template's own page adds) and the same steps (:mod:`rgmcad.making.steps`) as the template's
pages, the pictures seen from the side a template of the layout is seen from by default.
"""

from __future__ import annotations

import base64
import io
import logging
from dataclasses import dataclass
from html import escape

import numpy as np

log = logging.getLogger(__name__)
log.addHandler(logging.NullHandler())

PICTURE_PX = (320, 240)
"""Size of a step's picture in the reports, pixels."""


@dataclass(frozen=True)
class MakingReport:
    """``html``: the section of ``report.html``; ``markdown``: lines of ``report.md``, the
    first one blank."""

    html: str
    markdown: tuple[str, ...]


def stands_of(supports: dict | None) -> list:
    """The stands of a run's ``supports.json`` (:mod:`rgmcad.runs.supports_text`); none where
    it has none or one is malformed (logged: the report is written without them)."""
    from rgmcad.making.stands import stand_from_json

    try:
        return [stand_from_json(s) for s in (supports or {}).get("stands", [])]
    except (ValueError, AttributeError) as exc:
        log.warning("supports.json: %s; the report's steps leave the stands out", exc)
        return []


def _png(picture: np.ndarray) -> bytes:
    from PIL import Image

    out = io.BytesIO()
    Image.fromarray(np.asarray(picture, np.uint8)).save(out, format="PNG", optimize=True)
    return out.getvalue()


def making_report(scenario, scene, ball_mass=None, stands=()) -> MakingReport:
    """The bill and the steps of the posed ``scene`` (``ball_mass``: the measurement kept in
    the run, :func:`rgmcad.making.ball_mass.read_cached`; ``stands``: those of ``rgmcad
    supports``, :mod:`rgmcad.making.stands`)."""
    from rgmcad.making.bom import bill_of_materials, support_lines
    from rgmcad.making.steps import assembly_steps, render_steps, supports_of

    bill = bill_of_materials(scenario, scene, ball_mass=ball_mass,
                             supports=support_lines(stands))
    steps = assembly_steps(scenario, scene, supports_of(stands))
    pictures = render_steps(scenario, scene, steps, width=PICTURE_PX[0], height=PICTURE_PX[1],
                            stands=stands)
    md = ["", "## Bill of materials", "",
          "What to buy or make (the template adds its paper and tape; `rgmcad template "
          "--bom-json` prints it all):", ""]
    md += [f"  - {line.strip()}" if line.startswith("  ") else f"- **{line}**"
           for line in bill.text_lines()]
    md += ["", "## Assembly steps", "",
           "In the template's order (the numbers of the parts on its sheets); each step's "
           "picture is in report.html.", ""]
    items = []
    for step, picture in zip(steps, pictures, strict=True):
        data = _png(picture)
        md.append(f"{step.number}. {step.text}")
        items.append(f'<li style="width:{PICTURE_PX[0] + 10}px">'
                     f'<img src="data:image/png;base64,{base64.b64encode(data).decode()}" '
                     f'alt="step {step.number}" width="{PICTURE_PX[0]}"><br>'
                     f"<b>{step.number}.</b> {escape(step.text)}</li>")
    rows = "".join(f"<tr><td>{line.count}</td><td>{escape(line.kind)}</td>"
                   f"<td>{escape(line.what)}</td><td>{escape(line.note)}</td></tr>"
                   for line in bill.lines)
    html = ("<h2>Bill of materials</h2><p>What to buy or make; the printed template adds its "
            "paper and tape.</p><table><tr><th>count</th><th>kind</th><th>what</th>"
            f"<th>note</th></tr>{rows}</table>"
            "<h2>Assembly steps</h2><p>In the template's order (the numbers of the parts on its "
            "sheets); orange: what the step places.</p>"
            '<ol class="steps" style="display:flex;flex-wrap:wrap;gap:1em;'
            f'list-style:none;padding:0">{"".join(items)}</ol>')
    return MakingReport(html, tuple(md))
