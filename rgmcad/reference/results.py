"""Results tables made from the measurements' JSON files, never copied by hand: a results page
holds a marker ``<!-- table: PATH -->`` (PATH from the repository's root, a glob for the
summary of several benchmarks) and the site's build puts the table of that file in its place
(``docs/hooks.py``). A section quoting the engineering log holds ``<!-- measured under the
physics of DATE -->`` instead. Under each table, the file it came from and the physics revision it was
measured under (:mod:`rgmcad.sim.revision`); a table measured under an earlier revision says
so in a warning, so that a page never passes superseded figures off as current.
"""

from __future__ import annotations

import fnmatch
import json
import re
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rgmcad.runs.benchmark_table import power_note, table_rows
from rgmcad.runs.hand import rate_text
from rgmcad.runs.robustness import wilson_interval
from rgmcad.sim.revision import PHYSICS_REVISION

__all__ = ["hand_table", "physics_settings_table", "benchmark_table", "benchmarks_glance",
           "TABLES", "fill"]

MARKER = re.compile(r"<!-- table: (\S+) -->")
MEASURED = re.compile(r"<!-- measured under the physics of (\S+) -->")
"""A section whose figures come from the engineering log rather than a file says when they
were measured; the build turns it into the note or warning a table gets."""


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


def physics_settings_table(results: dict) -> str:
    """``tools/physics_settings.py``'s results: each scenario's `solved` layout under the
    time step and solver iterations as written and three finer variants, nominal and built by
    hand, with the builds that flipped against the settings as written (paired by draw)."""
    from scipy.stats import binomtest

    out = ["| scenario | settings | nominal | works when built by hand | flipped vs as written "
           "(works -> fails / fails -> works) | paired p | s per build |",
           "|---|---|---|---|---|---|---|"]
    for scenario, variants in results["scenarios"].items():
        base = [o for o, _ in variants["as written"]["builds"]]
        for name, v in variants.items():
            outcomes = [o for o, _ in v["builds"]]
            n = min(len(outcomes), len(base))
            wins = sum(o == "success" for o in outcomes)
            low, high = wilson_interval(wins, len(outcomes))
            lost = sum(a == "success" != b for a, b in zip(base[:n], outcomes[:n], strict=True))
            won = sum(b == "success" != a for a, b in zip(base[:n], outcomes[:n], strict=True))
            outcome, resolved, _ = v["nominal"]
            nominal = outcome + ("" if resolved is None else f" at {resolved:.2f} s")
            s = v["settings"]
            settings = f"{name} ({s['timestep'] * 1000:g} ms, {s['solver_iterations']} it.)"
            flips = "-" if name == "as written" else f"{lost} / {won}"
            # exact McNemar test: are flips one way as likely as the other?
            p = "-" if name == "as written" else (
                f"{binomtest(min(lost, won), lost + won).pvalue:.2f}" if lost + won else "1.00")
            seconds = np.mean([t for _, t in v["builds"]]) if v["builds"] else float("nan")
            out.append(f"| {scenario} | {settings} | {nominal} | {wins}/{len(outcomes)}: "
                       f"{rate_text(wins / max(len(outcomes), 1), float(low), float(high))} | "
                       f"{flips} | {p} | {seconds:.3f} |")
    return "\n".join(out)


def benchmark_table(table: dict) -> str:
    """One ``rgmcad benchmark`` (its ``benchmark.json``): a row per method and given layout,
    rho_g under placement errors and with physical errors too, paired against ours."""
    head = (f"B = {table['budget_sims']:,} simulations per method run; "
            f"{len(table['seeds'])} trials (seeds {table['seeds'][0]}-{table['seeds'][-1]}); "
            f"rho_l from {table['samples_per_radius']} valid layouts per radius.")
    if table.get("earlier_rows"):
        head += " Rows of earlier calls in the same folder: " + ", ".join(
            table["earlier_rows"]) + "."
    note = power_note(table)
    return "\n".join([head, "", *table_rows(table)] + (["", note] if note else []))


def _best_baseline(rows: list[dict], key: str) -> dict | None:
    # ours with one global model (Fig. 16) is ours, not a baseline; a given layout has no cost
    others = [r for r in rows if r["method"] not in ("ours", "full")
              and r.get(f"{key}_mean") is not None and r.get("simulations_mean") is not None]
    return max(others, key=lambda r: r[f"{key}_mean"], default=None)


def benchmarks_glance(tables: dict[str, dict]) -> str:
    """Several benchmarks, one line each: ours, the best baseline and their ratio, under
    placement errors / with physical errors too, and a given layout's row where there is one."""
    out = ["| scenario | d | B | ours | best baseline | ours / best | given layout |",
           "|---|---|---|---|---|---|---|"]
    for table in sorted(tables.values(), key=lambda t: (t["scenario"], t["budget_sims"])):
        rows = {r["method"]: r for r in table["rows"]}
        ours = rows.get("ours")
        if ours is None:
            continue
        cells = {"ours": [], "best": [], "ratio": []}
        for key in ("rho_g", "physics_rho_g"):
            best = _best_baseline(table["rows"], key)
            mine = ours.get(f"{key}_mean")
            cells["ours"].append("-" if mine is None else f"{mine:.3f}")
            cells["best"].append("-" if best is None else
                                 f"{best['label'].split(' ')[0]} {best[f'{key}_mean']:.3f}")
            cells["ratio"].append("-" if best is None or mine is None or not best[f"{key}_mean"]
                                  else f"{mine / best[f'{key}_mean']:.2f}x")
        given = [r for r in table["rows"] if r.get("simulations_mean") is None]
        given_text = "; ".join(
            f"{r['label']} {r['rho_g_mean']:.3f} / " + (
                "-" if r.get("physics_rho_g_mean") is None else f"{r['physics_rho_g_mean']:.3f}")
            for r in given) or "-"
        d = len(ours["vectors"][0]) if ours.get("vectors") else "?"
        out.append(f"| {table['scenario']} | {d} | {table['budget_sims']:,} | "
                   f"{' / '.join(cells['ours'])} ({ours['trials']} trials) | "
                   f"{' / '.join(cells['best'])} | {' / '.join(cells['ratio'])} | {given_text} |")
    return "\n".join(out)


TABLES: dict[str, Callable[[dict], str]] = {
    "docs/hand-acceptance.json": hand_table,
    "docs/physics-settings.json": physics_settings_table,
    "docs/results/runs/benchmark-*.json": benchmark_table,
}
"""The files a marker may name (fnmatch patterns), and the table each makes."""

GLANCES: dict[str, Callable[[dict[str, dict]], str]] = {
    "docs/results/runs/benchmark-*.json": benchmarks_glance,
}
"""Globs a marker may name for one table over every file that matches."""


UNTRACKED = "before 2026-12-08"
"""What a file that records no revision was measured under: revisions were first recorded on
2026-12-08."""


def _revision(data) -> str | None:
    """The physics revision a file records; for one entry per run (hand-acceptance.json), the
    oldest of its runs', None if any run records none."""
    if "physics_revision" in data:
        return data["physics_revision"]
    runs = [v.get("physics_revision") for v in data.values() if isinstance(v, dict)
            and "scenario" in v]
    return min(runs) if runs and None not in runs else None


def _provenance(source: str, revisions: list[str | None]) -> str:
    """A note that ``source`` ("From `FILE`", "The figures of this section") was measured under
    the current physics, or a warning box naming the earlier revisions it was measured under."""
    stale = sorted({r or UNTRACKED for r in revisions if r != PHYSICS_REVISION})
    if not stale:
        return f"*{source}, measured under the current physics ({PHYSICS_REVISION}).*"
    return (f"!!! warning \"Measured under earlier physics\"\n    {source}, measured under the "
            f"physics of {', '.join(stale)}; the simulation has changed since (current: "
            f"{PHYSICS_REVISION}, see the engineering log): to be measured again.")


def _load(path: Path) -> dict:
    return json.loads(path.read_text(encoding="utf-8"))


def fill(markdown: str, root: Path) -> str:
    """``markdown`` with each marker replaced by its file's table and provenance; an unknown
    or missing file is an error (a page must not quietly lose its table)."""
    def table(match):
        name = match.group(1)
        if name in GLANCES:
            paths = sorted(root.glob(name))
            if not paths:
                raise ValueError(f"no file matches {name}")
            data = {p.name: _load(p) for p in paths}
            names = [str(p.relative_to(root)) for p in paths]
            files = ", ".join(f"`{n}`" for n in names)
            return GLANCES[name](data) + "\n\n" + _provenance(
                f"From {files}", [_revision(d) for d in data.values()])
        maker = next((m for pattern, m in TABLES.items() if fnmatch.fnmatchcase(name, pattern)),
                     None)
        if maker is None:
            raise ValueError(f"no table is made from {name}; known: {', '.join(TABLES)}")
        data = _load(root / name)
        return maker(data) + "\n\n" + _provenance(f"From `{name}`", [_revision(data)])

    def measured(match):
        return _provenance("The figures of this section", [match.group(1)])

    return MEASURED.sub(measured, MARKER.sub(table, markdown))
