"""The template's SVG: the whole drawing at 1:1, user units millimetres, one file.

SVG ``x = u - u0`` and ``y = v1 - v`` for the drawing's extent ``(u0, v0, u1, v1)``.
"""

from __future__ import annotations

from pathlib import Path
from xml.sax.saxutils import escape, quoteattr

from rgmcad.printing.drawing import Drawing, TextItem


def _hex(rgb) -> str:
    return "#" + "".join(f"{round(255 * c):02x}" for c in rgb)


def write_svg(path: Path, drawing: Drawing, title: str) -> None:
    """Write ``drawing`` to ``path`` as SVG, titled ``title``."""
    u0, v0, u1, v1 = drawing.extent
    w, h = u1 - u0, v1 - v0

    def xy(pts):
        return " ".join(f"{x - u0:.4f},{v1 - y:.4f}" for x, y in pts)

    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.4f}mm" height="{h:.4f}mm" '
        f'viewBox="0 0 {w:.4f} {h:.4f}">',
        f"<title>{escape(title or 'rgmcad assembly template')}</title>",
        f"<desc>1:1, user units are millimetres; drawing u = x + {u0:.4f}, "
        f"v = {v1:.4f} - y</desc>",
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
    path.write_text("\n".join(out) + "\n", encoding="utf-8")
