"""The template's SVG: the whole drawing at 1:1, user units millimetres, one file.

SVG ``x = u - u0`` and ``y = v1 - v`` for the drawing's extent ``(u0, v0, u1, v1)``; the
file's ``<desc>`` says so with the numbers, and how ``(u, v)`` lie in the world.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from rgmcad.files import naming
from rgmcad.printing.drawing import Drawing, TextItem
from rgmcad.printing.plane import PlaneFrame


def _hex(rgb) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


def _axis(direction) -> str:
    """A world direction in words: ``+x`` for an axis, else its components."""
    d = np.asarray(direction, float)
    k = int(np.argmax(np.abs(d)))
    if abs(abs(d[k]) - 1.0) < 1e-9:
        return f"{'+' if d[k] > 0 else '-'}{'xyz'[k]}"
    return "(" + ", ".join(f"{c:.4f}" for c in d) + ")"


def _plus(value: float) -> str:
    """``+ 3.000`` or ``- 3.000``: a term added, its sign folded in."""
    return f"{'-' if value < 0 else '+'} {abs(value):.3f}"


def coordinates_note(drawing: Drawing, frame: PlaneFrame) -> str:
    """How SVG user units relate to the template plane and the world, in one sentence."""
    u0, _, _, v1 = drawing.extent
    origin = ", ".join(f"{1000 * c:.1f}" for c in frame.origin)
    return (f"1:1, user units are millimetres. A point at drawing millimetres (u, v) is at "
            f"SVG x = u {_plus(-u0)}, y = {v1:.3f} - v; u runs along world "
            f"{_axis(frame.u_axis)} and v along world {_axis(frame.v_axis)}, from the world "
            f"point ({origin}) mm.")


def write_svg(path: Path, drawing: Drawing, title: str, frame: PlaneFrame) -> None:
    """Write ``drawing`` (in the plane ``frame``) to ``path`` as SVG, titled ``title``."""
    u0, v0, u1, v1 = drawing.extent
    w, h = u1 - u0, v1 - v0

    def xy(pts):
        return " ".join(f"{x - u0:.4f},{v1 - y:.4f}" for x, y in pts)

    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.4f}mm" height="{h:.4f}mm" '
        f'viewBox="0 0 {w:.4f} {h:.4f}">',
        f"<title>{escape(title or 'rgmcad assembly template')}</title>",
        f"<desc>{escape(coordinates_note(drawing, frame))}</desc>",
    ]
    for it in drawing.items:
        if isinstance(it, TextItem):
            anchor = f' text-anchor="{it.anchor}"' if it.anchor != "start" else ""
            weight = ' font-weight="bold"' if it.bold else ""
            out.append(
                f'<text x="{it.x - u0:.3f}" y="{v1 - it.y:.3f}" font-family="Helvetica, '
                f'Arial, sans-serif" font-size="{it.size:.2f}"{weight}{anchor} '
                f'fill="{_hex(it.colour)}">{escape(it.text)}</text>'
            )
            continue
        d = " ".join(("M " + xy(r) + (" Z" if it.closed else "")) for r in it.rings)
        attrs = [f'd="{d}"']
        if it.ident:
            attrs.append(f"id={quoteattr(it.ident)}")
        if it.cls:
            attrs.append(f"class={quoteattr(it.cls)}")
        attrs.append(f'fill="{_hex(it.fill)}" fill-rule="evenodd"' if it.fill else 'fill="none"')
        if it.stroke is not None:
            attrs.append(f'stroke="{_hex(it.stroke)}" stroke-width="{it.width:.3f}"')
            if it.dash:
                attrs.append(f'stroke-dasharray="{" ".join(f"{v:g}" for v in it.dash)}"')
        out.append(f"<path {' '.join(attrs)}/>")
    out.append("</svg>")
    with naming(path):
        path.write_text("\n".join(out) + "\n", encoding="utf-8")
