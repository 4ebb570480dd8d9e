"""The live page's simulation worker: a process of its own (pybullet's engine is one per
process, and a simulation holds the interpreter), run by a one-process pool
(:mod:`rgmcad.live.session`).

Each task takes a :class:`Request`, the whole state of the page (the scenario file, the
layout, the slider values, the layout to compare with), loads the scenario and its parts
again only when the files' ``revision`` changed, and answers with plain data: never an
exception, whose pickling could fail. A scenario or part error is the line the command line
prints; any other exception is one line too.

Latest wins: the server raises a shared generation counter for every new request; a task
whose generation is behind it stops before it starts, and a running simulation stops within
a few physics steps (a step hook checks the counter), answering ``{"superseded": True}``.
"""

from __future__ import annotations

import atexit
import functools
import itertools
import logging
import os
import signal
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rgmcad.errors import RgmcadError, error_line
from rgmcad.live.errors import failure_line, file_line
from rgmcad.live.files import scenario_text

__all__ = ["Request", "init", "hello", "view", "sweep_point", "document"]

log = logging.getLogger(__name__)

CHECK_EVERY = 16
"""Physics steps between two looks at the generation counter (a look costs a microsecond)."""


@dataclass(frozen=True)
class Request:
    """What the page asks for, whole (so any task can run in a fresh worker)."""

    scenario: str
    build_dir: str
    parts_dir: str | None
    revision: int  # the files' revision: the scenario is loaded again when it changes
    generation: int  # superseded once the shared counter passes it
    layout: str = "initial"  # the layout the sliders start from
    changes: tuple[tuple[str, float], ...] = ()  # parameters set by the sliders, real units
    compare: str | None = None  # a layout shown beside it
    extra: dict = field(default_factory=dict)  # more layouts: name -> {param: value} or a file


class Superseded(Exception):
    """A newer request came while this one ran."""


_state: dict = {"generation": None, "loaded": None, "engine": None, "stores": {}}


def init(generation, parent: int, level: int = logging.WARNING) -> None:
    """The worker's initializer: ``generation`` is the shared counter; the worker leaves
    Ctrl-C to the server (which stops it), and exits if the server dies without doing so."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    logging.basicConfig(level=level, format="%(levelname)s: %(message)s")
    _state["generation"] = generation

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="rgmcad-live-parent", daemon=True).start()
    atexit.register(_close)


def _close() -> None:
    """Drop the engine and the derived data before the interpreter goes (manifold3d's
    bindings complain of solids still alive at exit)."""
    loaded, _state["loaded"] = _state["loaded"], None
    if loaded is not None:
        loaded.cache.close()
    if _state["engine"] is not None:
        _state["engine"].close()
        _state["engine"] = None


def hello() -> int:
    """The worker's process id, once the simulation modules are imported."""
    import rgmcad.sim.run  # noqa: F401
    import rgmcad.viewer.recording  # noqa: F401

    return os.getpid()


def _superseded(generation: int) -> bool:
    shared = _state["generation"]
    return shared is not None and shared.value > generation


def _hook(generation: int):
    count = itertools.count()

    def hook(world, t):
        if next(count) % CHECK_EVERY == 0 and _superseded(generation):
            raise Superseded

    return hook


@dataclass
class _Loaded:
    key: tuple
    scenario: object
    parts: dict
    cache: object


def _load(req: Request) -> _Loaded:
    """The scenario and its parts, loaded again when the files changed; parts come from one
    store per part folder (read from disk once), derived data from one cache while the
    scenario's parts stay the same."""
    from rgmcad.parts.store import PartStore
    from rgmcad.scene.bodies import load_parts
    from rgmcad.scene.loader import load_scenario
    from rgmcad.sim.cache import PartCache

    key = (req.scenario, req.parts_dir, req.build_dir, req.revision)
    loaded = _state["loaded"]
    if loaded is not None and loaded.key == key:
        return loaded
    _state["loaded"] = None  # a file that fails to load is tried again on the next request
    scenario = load_scenario(req.scenario, parts_dir=None if req.parts_dir is None
                             else Path(req.parts_dir))
    store = _state["stores"].setdefault(req.build_dir, PartStore(req.build_dir))
    parts = load_parts(scenario, store)
    if loaded is not None and {id(p) for p in loaded.parts.values()} == {id(p) for p in parts.values()}:
        cache = loaded.cache
    else:
        if loaded is not None:
            loaded.cache.close()
        cache = PartCache()
    _state["loaded"] = _Loaded(key, scenario, parts, cache)
    return _state["loaded"]


def _engine():
    if _state["engine"] is None:
        from rgmcad.sim.engine import Engine

        _state["engine"] = Engine(renderer=False)
    return _state["engine"]


def _layout(scenario, name: str, extra: dict) -> tuple[np.ndarray, str]:
    """Real values of a layout of the scenario or of ``extra``; the initial layout (with a
    note) when the scenario no longer has it."""
    from rgmcad.scene.design_space import values_from_mapping
    from rgmcad.scene.layout_files import load_layout_file

    if name in scenario.layouts:
        return values_from_mapping(scenario, scenario.layouts[name]), ""
    source = extra.get(name)
    if isinstance(source, dict):
        free = {f.name for f in scenario.free}
        return values_from_mapping(scenario, {k: v for k, v in source.items() if k in free}), ""
    if isinstance(source, str):
        return load_layout_file(scenario, Path(source)), ""
    return (values_from_mapping(scenario, scenario.layouts["initial"]),
            f"the scenario has no layout {name!r} now: showing initial")


def _values(scenario, req: Request) -> tuple[np.ndarray, str, str]:
    """(values, the layout's name with the slider changes, a note) of the request."""
    values, note = _layout(scenario, req.layout, req.extra)
    index = {f.name: i for i, f in enumerate(scenario.free)}
    shown = []
    for name, value in req.changes:
        if name in index:
            values[index[name]] = value
            shown.append(f"{name}={value:g}")
    return values, ", ".join([req.layout, *shown]), note


def _answer(task):
    """The task's answer as plain data: a superseded run, an error line, or its result."""

    @functools.wraps(task)  # pickled by name: the pool finds ``view`` as the module holds it
    def run(req: Request, *args):
        if _superseded(req.generation):
            return {"superseded": True}
        try:
            return task(req, *args)
        except Superseded:
            return {"superseded": True}
        except RgmcadError as exc:
            text = scenario_text(req.scenario)
            return {"error": error_line(exc), "line": file_line(exc, req.scenario, text)}
        except Exception as exc:  # noqa: BLE001 - any failure is one line on the page
            log.debug("live task failed", exc_info=True)
            return {"error": failure_line(exc), "line": None}

    return run


def _record(loaded: _Loaded, values, req: Request, title: str):
    """(result, replay) of one layout: the run recorded, or a still frame of an invalid one."""
    from rgmcad.live.views import still_replay
    from rgmcad.scene.bodies import make_scene
    from rgmcad.viewer.recording import record_replay

    scenario = loaded.scenario
    result, replay = record_replay(scenario, values, loaded.parts, title=title,
                                   engine=_engine(), cache=loaded.cache,
                                   hooks=(_hook(req.generation),))
    if replay is None:
        scene = make_scene(scenario, values, loaded.parts)
        replay = still_replay(scenario, scene, result.validity, title)
    return result, replay


def _info(scenario, values, layout: str, changed) -> dict:
    from rgmcad.live.views import display, display_unit

    return {"scenario": scenario.name, "layout": layout, "layouts": list(scenario.layouts),
            "events": list(scenario.events),
            "free": [{"name": f.name, "unit": display_unit(f.unit),
                      "low": display(f.unit, f.low), "high": display(f.unit, f.high),
                      "value": display(f.unit, v), "changed": f.name in changed}
                     for f, v in zip(scenario.free, values, strict=True)]}


@_answer
def view(req: Request) -> dict:
    """Simulate the page's layout (and the one it is compared with), recorded: the summary
    of each, the scenario's free parameters and layouts, and the viewer's page."""
    from rgmcad.live.views import side_by_side, summary, viewer_html

    start = time.perf_counter()
    loaded = _load(req)
    loaded_at = time.perf_counter()
    scenario = loaded.scenario
    values, name, note = _values(scenario, req)
    result, replay = _record(loaded, values, req, f"{scenario.name}, layout {name}")
    answer = {"info": _info(scenario, values, name, dict(req.changes)), "main": summary(result), "note": note,
              "compare": None}
    shown = replay
    if req.compare is not None:
        other, other_note = _layout(scenario, req.compare, req.extra)
        compared, compared_replay = _record(loaded, other, req, req.compare)
        answer["compare"] = {"layout": req.compare, **summary(compared)}
        answer["note"] = "; ".join(n for n in (note, other_note) if n)
        shown = side_by_side(replay, compared_replay, ("A", "B"),
                             f"{scenario.name}: A {name}, B {req.compare}")
    simulated_at = time.perf_counter()
    answer["html"] = viewer_html(shown, "" if req.compare is None else
                                 f"A (left): {name}; B (right): {req.compare}")
    answer["seconds"] = {"load": loaded_at - start, "simulate": simulated_at - loaded_at,
                         "page": time.perf_counter() - simulated_at}
    return answer


@_answer
def sweep_point(req: Request, parameter: str, value: float) -> dict:
    """Simulate the page's layout with ``parameter`` set to ``value`` (real units): its
    outcome, the event it fails at, or the deepest overlap of an invalid layout."""
    from rgmcad.live.views import fails_at
    from rgmcad.sim.run import simulate

    loaded = _load(req)
    scenario = loaded.scenario
    values, _, _ = _values(scenario, req)
    index = [f.name for f in scenario.free].index(parameter)  # the server sends known names
    values[index] = value
    result = simulate(scenario, values, loaded.parts, engine=_engine(), cache=loaded.cache,
                      hooks=(_hook(req.generation),))
    overlap = None
    if result.validity is not None and result.validity.overlaps:
        o = max(result.validity.overlaps, key=lambda o: o.depth)
        overlap = f"{o.first} and {o.second} overlap by {o.depth * 1000:.2f} mm"
    return {"outcome": result.outcome.value, "fails_at": fails_at(result), "overlap": overlap}


@_answer
def document(req: Request, name: str) -> dict:
    """The layout file (:func:`~rgmcad.scene.layout_files.layout_document`) of the page's
    layout, named ``name``."""
    from rgmcad.scene.design_space import vector_from_values
    from rgmcad.scene.layout_files import layout_document

    scenario = _load(req).scenario
    values, shown, _ = _values(scenario, req)
    return {"document": layout_document(scenario, vector_from_values(scenario, values),
                                        name=name, made_from=shown)}
