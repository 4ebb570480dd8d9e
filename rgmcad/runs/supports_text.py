"""The supports section of a run's report, from the ``supports.json`` that ``rgmcad supports
--out RUN/supports`` leaves in the run directory (plain JSON: the runs stage does not import
:mod:`rgmcad.making`, which designs the stands)."""

from __future__ import annotations

from pathlib import Path

SUPPORTS_FILE = "supports/supports.json"
"""Where ``rgmcad supports --out RUN/supports`` leaves the stands, in a run directory."""


def read_supports(run_dir: Path) -> dict | None:
    """The run's ``supports.json`` (:data:`SUPPORTS_FILE`) as written, or None."""
    import json

    try:
        return json.loads((Path(run_dir) / SUPPORTS_FILE).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def supports_lines(doc: dict | None) -> list[str]:
    """The report's supports section (the first line blank) from a ``supports.json``."""
    if not doc:
        return []
    raised = [p for p in doc.get("parts", []) if not p.get("held_by")]
    lines = ["", "## Supports", "",
             f"{len(raised)} static parts are raised; {len(doc['stands'])} stands hold them "
             f"(`{SUPPORTS_FILE}`, with STL, STEP and card nets beside it). In {doc['runs']} "
             f"runs (the nominal one and runs built by hand) a stand was touched in "
             f"{doc['runs_touched']} and the outcome changed in {doc['runs_changed']}.", "",
             "| stand | holds | size (mm) | height (mm) | top tilt |", "|---|---|---|---|---|"]
    for st in doc["stands"]:
        lo, hi = st["height_mm"]
        lines.append(f"| {st['label']} | {st['part']} | {st['length_mm']:.1f} x "
                     f"{st['width_mm']:.1f} | {lo:.1f} to {hi:.1f} | {st['tilt_deg']:.1f}° |")
    lines += [f"- **{u['part']}**: {u['why']}" for u in doc.get("unsupported", [])]
    return lines
