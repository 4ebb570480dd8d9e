"""``rgmcad verify-print``: the scale a template sheet was printed at, from a scan or photo.

``rgmcad verify-print IMAGE`` measures it with :func:`rgmcad.printing.check.verify_print`.
"""

from __future__ import annotations

import json
from pathlib import Path

from rgmcad.cli.common import say

USES_BUILD_DIR = False


def configure(p) -> None:
    p.add_argument("image", help="a scan (with its dpi recorded) or a photo of one printed "
                   "sheet, the whole sheet in view on a darker background")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")


def run(args) -> int:
    from rgmcad.printing.check import verify_print

    check = verify_print(Path(args.image))
    if args.json:
        say(json.dumps({
            "image": check.path, "sheet": check.sheet, "paper": check.paper,
            "tag_ids": list(check.tag_ids), "scale": check.scale,
            "scale_error_percent": check.scale_error_percent,
            "scale_xy": list(check.scale_xy), "method": check.method,
            "residual_mm": check.residual_mm, "ok": check.ok, "message": check.message,
        }))
        return 0
    paper = f", {check.paper}" if check.paper else ""
    say(f"sheet {check.sheet}{paper} ({len(check.tag_ids)} marks, measured by "
        f"{'the scan resolution' if check.method == 'dpi' else 'the sheet edges'})")
    say(check.message)
    return 0
