"""One self-contained HTML page: the replay viewer (three.js, vendored in ``vendor/``), the
recorded run and any other sections, with nothing fetched when it is opened from disk."""

from __future__ import annotations

import json
from html import escape
from importlib import resources
from pathlib import Path

from rgmcad.files import write_atomic
from rgmcad.viewer.recording import Replay, replay_payload

__all__ = ["replay_section", "html_page", "write_replay_html"]

_SCRIPTS = {  # element id -> packaged file
    "rgmcad-three-core": "vendor/three.core.min.js",
    "rgmcad-three": "vendor/three.module.min.js",
    "rgmcad-orbit": "vendor/OrbitControls.js",
    "rgmcad-viewer": "assets/viewer.js",
}
_HELP = ('<p class="muted">Drag to turn the view, scroll to zoom, right-drag to pan; '
         "<kbd>r</kbd> or Reset view returns to the first view. Point at a part for its name; "
         "<kbd>n</kbd> or names shows them all. Space plays or pauses. 3D view by three.js (MIT "
         "licence, bundled in this file).</p>")
SPEEDS = (("1x", 1.0), ("1/4x", 0.25), ("1/10x", 0.1))


def _asset(name: str) -> str:
    return resources.files("rgmcad.viewer").joinpath(name).read_text(encoding="utf-8")


def _inert(text: str) -> str:
    """Script text that cannot close the ``<script>`` element holding it: the shipped scripts
    hold no ``</``; one that did would be refused here rather than break the page."""
    if "</" in text:
        raise ValueError("a script holding '</' cannot be embedded in a page as it is")
    return text


def _event_time(e: dict) -> str:
    return "" if e["time"] is None else repr(float(e["time"]))


def replay_section(payload: dict) -> str:
    """The viewer: 3D view, playback controls and the event timeline of ``payload``
    (:func:`~rgmcad.viewer.recording.replay_payload`)."""
    events = payload["events"]
    duration = max(payload["duration"], 1e-9)
    marks, items = [], []
    for e in sorted(events, key=lambda e: (e["time"] is None, e["time"] or 0.0)):
        name, state, when = escape(e["name"]), escape(e["state"]), _event_time(e)
        attrs = f'data-event="{name}" data-state="{state}" data-time="{when}"'
        if e["time"] is not None:
            marks.append(f'<span class="mark" {attrs} title="{name}: {state} at '
                         f'{e["time"]:.3f} s" style="left:{100 * e["time"] / duration:.2f}%">'
                         "</span>")
        label = {"success": "succeeds", "failure": "fails"}.get(e["state"], "never resolves")
        clock = "" if e["time"] is None else f" at {e['time']:.3f} s"
        parents = (f"the first of {' or '.join(e['after'])}" if e.get("join") == "any"
                   else ", ".join(e["after"]))
        after = f' <span class="after">after {escape(parents)}</span>' if e["after"] else ""
        items.append(f'<li {attrs} title="{escape(e.get("description") or "")}">'
                     f'<span class="when">{label}{clock}</span><code>{name}</code>{after}</li>')
    speeds = "".join(f'<button class="speed{" on" if s == 1.0 else ""}" data-speed="{s}">'
                     f"{label}</button>" for label, s in SPEEDS)
    outcome = escape(payload["outcome"])
    return f"""<section id="rgmcad-replay">
<div class="view" aria-label="3D replay: drag to orbit, scroll to zoom, right-drag to pan"></div>
<div class="controls">
<button class="play">Pause</button>
<input class="scrub" type="range" min="0" max="1000" value="0" aria-label="time">
<span class="clock">0.000 s</span>
{speeds}
<label><input class="loop" type="checkbox" checked> loop</label>
<label title="the parts' names (n)"><input class="names" type="checkbox"> names</label>
<button class="reset-view" title="back to the first view (r)">Reset view</button>
<span class="outcome {outcome}">{outcome}</span>
</div>
<div class="track">{"".join(marks)}<span class="playhead"></span></div>
<ul class="events">{"".join(items)}</ul>
</section>"""


def html_page(title: str, body: str, payload: dict | None) -> str:
    """A whole page: ``body`` (HTML holding :func:`replay_section` unless ``payload`` is
    None), the recorded run ``payload`` and the viewer's code."""
    scripts = ""
    if payload is not None:
        data = json.dumps(payload, separators=(",", ":")).replace("<", "\\u003c")
        scripts = "\n".join(
            [f'<script type="application/json" id="rgmcad-replay-data">{data}</script>']
            + [f'<script type="text/plain" id="{i}">{_inert(_asset(f))}</script>'
               for i, f in _SCRIPTS.items()]
            + [f"<script>{_inert(_asset('assets/loader.js'))}</script>"])
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="rgmcad">
<title>{escape(title)}</title>
<style>{_asset("assets/viewer.css")}</style>
</head><body><main>
{body}
{_HELP if payload is not None else ""}
</main>
{scripts}
</body></html>
"""


def write_replay_html(path: str | Path, replay: Replay) -> Path:
    """Write the replay page of one recorded run to ``path``."""
    payload = replay_payload(replay)
    body = (f"<h1>{escape(replay.title)}</h1>\n"
            f'<p class="muted">{len(replay.bodies)} bodies, {len(replay.times)} frames, '
            f"{replay.times[-1]:.3f} s simulated; outcome {escape(replay.outcome)}.</p>\n"
            + replay_section(payload))
    path = Path(path)
    write_atomic(path, html_page(replay.title, body, payload))  # whole, or the old page
    return path


def simulate_to_html(scenario, values, parts, path: str | Path, *, title: str | None = None,
                     rate: float | None = None, physics=None):
    """Simulate a layout (under ``physics``, a :class:`~rgmcad.scene.perturbation.PhysicsDraw`,
    if given), recording it, and write its replay page to ``path``; returns the
    :class:`~rgmcad.sim.run.SimulationResult`. An invalid layout (not simulated) gets a page
    without a 3D view."""
    from rgmcad.viewer.recording import DEFAULT_RATE, record_replay

    result, replay = record_replay(scenario, values, parts, title=title,
                                   rate=DEFAULT_RATE if rate is None else rate, physics=physics)
    if replay is not None:
        write_replay_html(path, replay)
        return result
    overlaps = "".join(f"<li>{escape(o.first)} and {escape(o.second)} overlap by "
                       f"{o.depth * 1000:.2f} mm</li>" for o in result.validity.overlaps)
    title = title or scenario.name
    body = (f"<h1>{escape(title)}</h1><p>This layout is invalid: its parts overlap at the "
            f"start, so it was not simulated.</p><ul>{overlaps}</ul>")
    write_atomic(path, html_page(title, body, None))
    return result
