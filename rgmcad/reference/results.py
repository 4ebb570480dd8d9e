"""Results tables made from the measurements' JSON files, never copied by hand: a results page
holds a marker ``<!-- table: PATH -->`` (PATH from the repository's root) and the site's build
puts the table of that file in its place (``docs/hooks.py``)."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

from rgmcad.runs.hand import rate_text

__all__ = ["hand_table", "TABLES", "fill"]

MARKER = re.compile(r"<!-- table: (\S+) -->")


def _rate(r: dict) -> str:
    return rate_text(r["rate"], *r["interval"])


def hand_table(results: dict) -> str:
    """``tools/hand_acceptance.py``'s results: each run's optimised layout against the
    scenario's own, works when built by hand, and the optimisation's time."""
    rows = ["| scenario | seed | optimised: works when built by hand | reference layout | "
            "optimize (s) |", "|---|---|---|---|---|"]
    for entry in results.values():
        ref = entry.get("reference")
        rows.append(f"| {Path(entry['scenario']).stem} | {entry['seed']} | "
                    f"{_rate(entry['optimum'])} | "
                    + (f"`{ref['layout']}` {_rate(ref)}" if ref else "-")
                    + f" | {entry['optimize_seconds']:.0f} |")
    return "\n".join(rows)


TABLES: dict[str, Callable[[dict], str]] = {"docs/hand-acceptance.json": hand_table}
"""The files a marker may name, and the table each makes."""


def fill(markdown: str, root: Path) -> str:
    """``markdown`` with each marker replaced by its file's table; an unknown file is an
    error (a page must not quietly lose its table)."""
    def table(match):
        name = match.group(1)
        if name not in TABLES:
            raise ValueError(f"no table is made from {name}; known: {', '.join(TABLES)}")
        return TABLES[name](json.loads((root / name).read_text(encoding="utf-8")))

    return MARKER.sub(table, markdown)
