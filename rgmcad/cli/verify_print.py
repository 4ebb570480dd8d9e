"""``rgmcad verify-print``: the scale a template sheet was printed at, from a scan or photo.

``rgmcad verify-print IMAGE`` measures it with :func:`rgmcad.printing.check.verify_print`.
Exit status 0 when a scale was measured (in tolerance or not: the message says), 1 when the
sheet was recognised but no scale could be measured (not flat, or no usable reference).
"""

from __future__ import annotations

import json
from pathlib import Path

from rgmcad.cli.common import say

USES_BUILD_DIR = False

_METHOD = {"dpi": "the scan resolution", "sheet-edges": "the sheet edges"}


def configure(p) -> None:
    p.add_argument("image", help="a scan (with its dpi recorded) or a photo of one printed "
                   "sheet: flat, its marks in view, and two opposite edges against a strip "
                   "of darker table")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def _num(value):
    return None if value is None else float(value)


def run(args) -> int:
    from rgmcad.printing.check import Verdict, verify_print

    check = verify_print(Path(args.image))
    status = 1 if check.verdict in (Verdict.NOT_FLAT, Verdict.NO_SCALE) else 0
    if args.json:
        say(json.dumps({
            "image": check.path, "sheet": check.sheet, "paper": check.paper,
            "tag_ids": list(check.tag_ids), "verdict": check.verdict.value,
            "scale": _num(check.scale), "scale_error_percent": _num(check.scale_error_percent),
            "scale_xy": [_num(v) for v in check.scale_xy], "method": check.method,
            "residual_mm": _num(check.residual_mm), "bow_mm": _num(check.bow_mm),
            "ok": check.ok,
            "message": check.message,
        }))
        return status
    paper = f", {check.paper}" if check.paper else ""
    how = f", measured by {_METHOD[check.method]}" if check.scale is not None else ""
    say(f"sheet {check.sheet}{paper} ({len(check.tag_ids)} marks{how})")
    say(check.message)
    return status
