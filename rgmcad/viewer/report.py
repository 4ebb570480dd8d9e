"""The page of a finished optimisation run, ``DIR/report.html``: the replay of the optimised
layout, the per-event probabilities with the weakest link, the placement tolerances (tight
ones highlighted), the run's figures and a link to the printable template.

It is written from what the run left in its directory (``result.json`` and the plots of
:mod:`rgmcad.runs.report`) and one simulation of the layout, recorded for the replay.
"""

from __future__ import annotations

import base64
import json
import shlex
from html import escape
from pathlib import Path

from rgmcad.files import write_atomic
from rgmcad.parts.store import DEFAULT_BUILD_DIR
from rgmcad.runs.hand_text import hand_headline, weak_link_lines
from rgmcad.runs.report import (
    HAND_PLOT,
    PROGRESS_PLOT,
    REPORT_FILE,
    ROBUSTNESS_PLOT,
    SLICE_PLOT,
    report_markdown,
    side_texts,
    tolerance_paragraphs,
    user_scale,
)
from rgmcad.runs.store import RESULT
from rgmcad.viewer.making import making_report, stands_of
from rgmcad.viewer.page import html_page, replay_section
from rgmcad.viewer.recording import record_replay, replay_payload

__all__ = ["REPORT_HTML", "TIGHT_MM", "TIGHT_DEG", "TEMPLATE_FILES", "write_run_report"]

REPORT_HTML = "report.html"
TIGHT_MM = 3.0
"""A position tolerance (either side) under this many mm is tight: about what a person
placing a part on a printed template by eye keeps to."""
TIGHT_DEG = 3.0
"""An angle tolerance (either side) under this many degrees is tight."""
TEMPLATE_FILES = ("template/template.pdf", "template.pdf")
"""Where the report looks for the printable template, relative to the run directory."""

_FIGURES = (
    (HAND_PLOT, "Success when a person builds it, by simulation: every part placed at random "
     "within the stated error of its printed place (the heading's error in proportion), the "
     "physical errors on top; 95 % bands. The square is the stated hand, with the most "
     "builds."),
    (SLICE_PLOT, "Predicted probability of success through the layout (star) along the two "
     "parameters it depends on most, the others held at the layout's values; contours at "
     "50 % and 90 %. Grey: the parts overlap there (nothing can be built, and the model, "
     "which never saw such a layout, is not drawn); a star against grey is pushed against "
     "a part."),
    (ROBUSTNESS_PLOT, "Predicted probability of success when every part is placed with a "
     "random error (Gaussian, this standard deviation in mm for positions and degrees for "
     "angles), from the learnt model."),
    (PROGRESS_PLOT, "Exploration history: whole-chain successes as the simulations went, one "
     "colour per stage (exploration, then active learning of the weakest events)."),
)


def write_run_report(run_dir: str | Path, scenario_path: str | Path, *,
                     build_dir: str | Path = DEFAULT_BUILD_DIR,
                     parts_dir: str | Path | None = None) -> Path:
    """Write ``run_dir/report.html`` for the finished run in ``run_dir`` of the scenario at
    ``scenario_path`` (a file or a shipped scenario's name); returns its path."""
    from rgmcad.making.ball_mass import read_cached
    from rgmcad.runs.supports_text import read_supports, supports_lines
    from rgmcad.scene.bodies import load_parts, make_scene
    from rgmcad.scene.design_space import bounds
    from rgmcad.scene.loader import load_scenario
    from rgmcad.shipped import scenario_path as shipped_path

    run_dir = Path(run_dir)
    summary = json.loads((run_dir / RESULT).read_text())
    scenario = load_scenario(scenario_path, parts_dir=parts_dir)
    values = [summary["values"][f.name] for f in scenario.free]
    parts = load_parts(scenario, build_dir)
    result, replay = record_replay(scenario, values, parts,
                                   title=f"{scenario.name}: optimised layout")
    payload = None if replay is None else replay_payload(replay)
    low, high = bounds(scenario)
    title = f"{scenario.name}: optimised layout"
    supports = read_supports(run_dir)  # rgmcad supports --out RUN/supports, if it was run
    making = making_report(scenario, make_scene(scenario, values, parts), read_cached(
        run_dir, shipped_path(scenario_path), values), stands_of(supports))  # both reports
    write_atomic(run_dir / REPORT_FILE, report_markdown(scenario, summary, low, high, [
        *supports_lines(supports), *making.markdown]))
    body = [f"<h1>{escape(title)}</h1>", _overview(summary, result),
            "<h2>Replay of the optimised layout</h2>",
            replay_section(payload) if payload else
            "<p>The layout is invalid (its parts overlap), so there is nothing to replay.</p>",
            _events(summary, result), _placement(scenario, summary, low, high), making.html,
            _figures(run_dir), _template(run_dir, _scenario_argument(scenario_path), summary)]
    path = run_dir / REPORT_HTML
    write_atomic(path, html_page(title, "\n".join(body), payload))  # whole, or the old page
    return path


def _overview(s: dict, result) -> str:
    weakest = s["weakest_event"]
    weakest_p = s.get("weakest_probability", s["event_probabilities"].get(weakest, 1.0))
    stages = ", ".join(f"{escape(k)} {v}" for k, v in s["simulations_by_stage"].items())
    hand = "" if not s.get("hand") else (
        f"<li>built by hand: <b>{escape(hand_headline(s['hand']))}</b><br>"
        + "<br>".join(escape(line.strip()) for line in weak_link_lines(s["hand"], most=3))
        + "</li>")
    return (f"<ul>{hand}<li>predicted probability of success: <b>{s['probability']:.3f}</b>; "
            f"weakest link: <code>{escape(str(weakest))}</code> ({weakest_p:.3f})</li>"
            f"<li>this layout simulated now: <b>{escape(result.outcome.value)}</b> "
            f"({result.n_success} of {len(result.events)} events); chosen as "
            f"{escape(s['source'])}</li>"
            f"<li>{s['simulations']} simulations ({s['successes']} successes; {stages}) in "
            f"{s['wall_time']:.0f} s; seed {s['seed']}, budget {escape(str(s['budget']))}</li>"
            f'<li>layout file: <a href="{escape(Path(s["layout"]).name)}">'
            f"{escape(Path(s['layout']).name)}</a> (give it to <code>--layout</code>)</li></ul>")


def _near_failures(s: dict) -> tuple[str, dict[str, str]]:
    """(column header, {event: cell}) of where the layouts near the result failed first
    (``optimize --robustness N``: within ``CLOSE_IN``, per kind of error); ("", {}) without."""
    r = s.get("robustness") or {}
    figs = [f["failures"]["close_in"] for f in (r, r.get("physics")) if f and f.get("failures")]
    if not figs:
        return "", {}
    n, radius = figs[0]["layouts"], figs[0]["radius"]
    kinds = "placement errors" + (" / + physical errors" if len(figs) > 1 else "")
    header = f"failed first, of {n} layouts within {radius:g} ({kinds})"
    cells = {name: " / ".join(str(f["failed"].get(name, 0)) for f in figs)
             for name in s["event_probabilities"]}
    return header, cells


def _events(s: dict, result) -> str:
    rows = []
    simulated = {e.name: e for e in result.events}
    near_header, near = _near_failures(s)
    for name, p in s["event_probabilities"].items():
        weakest = name == s["weakest_event"]
        f = s.get("factors", {}).get(name, {})
        e = simulated.get(name)
        seen = "" if e is None else e.state.value + ("" if e.time is None else
                                                     f" at {e.time:.3f} s")
        rows.append(f'<tr class="{"weakest" if weakest else ""}"><td><code>{escape(name)}'
                    f"</code>{' (weakest link)' if weakest else ''}</td><td>{p:.3f}</td>"
                    f'<td style="text-align:left"><span class="bar" style="width:{p * 8:.2f}rem">'
                    f"</span></td><td>{escape(seen)}</td><td>{escape(str(f.get('model', '')))}"
                    f"</td><td>{escape(', '.join(f.get('dims', [])) or '-')}</td>"
                    + (f"<td>{near[name]}</td>" if near else "") + "</tr>")
    return ("<h2>Events</h2><p>Probability of each event given that the events it waits for "
            "happened, predicted by the learnt model at this layout; the run succeeds when "
            "all do. The weakest link is the one most likely to break the chain.</p>"
            "<table><tr><th>event</th><th>P(success | parents)</th><th></th>"
            "<th>in the replay</th><th>model</th><th>depends on</th>"
            + (f"<th>{escape(near_header)}</th>" if near else "") + "</tr>"
            + "".join(rows) + "</table>")


def _placement(scenario, s: dict, low, high) -> str:
    rows = []
    n_tight = 0
    for j, f in enumerate(scenario.free):
        k, unit = user_scale(f)
        texts = side_texts(s, f.name, k)
        pushed = [t.startswith("push") for t in texts]
        tight = any(v * k < (TIGHT_DEG if unit == "deg" else TIGHT_MM) and not p
                    for v, p in zip(s["tolerances"][f.name], pushed, strict=True))
        n_tight += tight
        down, up = (escape(t).replace("-", "&minus;", 1) if not p else escape(t)
                    for t, p in zip(texts, pushed, strict=True))
        rows.append(f'<tr class="{"tight" if tight else ""}"><td><code>{escape(f.name)}</code>'
                    f"{' (tight)' if tight else ''}</td><td>{s['values'][f.name] * k:.1f} "
                    f"{unit}</td><td>{down}</td><td>{up}</td>"
                    f"<td>{low[j] * k:.1f} to {high[j] * k:.1f}</td></tr>")
    note = "".join(f"<p>{escape(n)}</p>" for n in tolerance_paragraphs(s))
    return ("<h2>Placement tolerances</h2><p>How far each part may be misplaced, one "
            "parameter at a time, before the predicted success drops below 90 % of its value "
            "here" + (f"; each side then simulated at {check['points_per_side']} places up to "
                      "its bound, and narrowed where one failed" if (
                          check := s.get("tolerance_check")) else
                      " (the model's figures: the layout did not succeed, nothing was "
                      "simulated)") + f". Highlighted: tight ones (under {TIGHT_MM:g} mm or "
            f"{TIGHT_DEG:g} degrees on a side), {n_tight} of {len(rows)}: place those with "
            "care.</p>"
            "<table><tr><th>parameter</th><th>value</th><th>may move down</th>"
            "<th>may move up</th><th>range</th></tr>" + "".join(rows) + "</table>" + note)


def _figures(run_dir: Path) -> str:
    out = []
    for name, caption in _FIGURES:
        path = run_dir / name
        if not path.is_file() or (name == ROBUSTNESS_PLOT and (run_dir / HAND_PLOT).is_file()):
            continue  # the model's guess under errors, where nothing was simulated
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        out.append(f'<figure><img src="data:image/png;base64,{data}" alt="{escape(name)}">'
                   f"<figcaption>{escape(caption)}</figcaption></figure>")
    return f'<h2>Figures</h2><div class="figures">{"".join(out)}</div>' if out else ""


def _scenario_argument(scenario_path: str | Path) -> str:
    """The scenario as a command pasted anywhere finds it: a file by its absolute path, a
    shipped scenario by its name."""
    given = Path(scenario_path)
    return str(given.resolve()) if given.is_file() else str(scenario_path)


def _absolute(path: str) -> str:
    return str(Path(path).resolve()) if Path(path).exists() else path


def _template(run_dir: Path, scenario_argument: str, s: dict) -> str:
    for name in TEMPLATE_FILES:
        if (run_dir / name).is_file():
            return (f'<h2>Printable template</h2><p><a href="{escape(name)}">{escape(name)}</a>: '
                    "print it at 100 %, tape the sheets together and place each part on its "
                    "outline.</p>")
    command = shlex.join(["rgmcad", "template", scenario_argument, "--layout",
                          _absolute(s["layout"]), "--out", str(run_dir.resolve() / "template")])
    return ("<h2>Printable template</h2><p>None yet. Make one beside this report (it is then "
            "linked here the next time the report is written, e.g. by the same "
            f"<code>rgmcad optimize</code> command):</p><pre>{escape(command)}</pre>")
