"""The live page's state on the server, and the work it hands to the simulation worker.

One :class:`Session` per server: the layout the pages show (a named layout and the slider
changes), the layout it is compared with, the last result, the sweep, and the open pages,
which all see the same state (a change made on one page shows on every page). Simulations
run in one worker process (:mod:`rgmcad.live.worker`), never in the event loop; every new
request raises the generation counter, which stops the running one (latest wins).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import logging
import math
import multiprocessing
import os
import re
import signal
import threading
import time
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

import numpy as np

from rgmcad.live import worker
from rgmcad.live.files import read_saved, write_saved
from rgmcad.live.views import real

__all__ = ["LiveOptions", "Session", "SWEEP_POINTS", "MAX_SWEEP_POINTS"]

log = logging.getLogger(__name__)

SWEEP_POINTS = 21
MAX_SWEEP_POINTS = 201
LAYOUT_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
STOP_WITHIN = 3.0
"""Seconds the worker has to stop when the server does, before it is killed."""


@dataclass(frozen=True)
class LiveOptions:
    """What ``rgmcad live`` was asked for.

    ``layouts``: the layout file the page's Save button writes. ``files``: layout files
    given on the command line, offered by their path as given (the page names one of them,
    never a path of its own). ``layout``, ``compare``: the layouts shown at the start.
    """

    scenario: str
    build_dir: str
    layouts: str
    parts_dir: str | None = None
    layout: str = "initial"
    compare: str | None = None
    files: tuple[str, ...] = ()
    host: str = "127.0.0.1"
    port: int = 0
    log_level: int = logging.WARNING


class Session:
    """The state every page shows, and the jobs that update it."""

    def __init__(self, options: LiveOptions):
        self.options = options
        self.sockets: set = set()
        self.revision = 0  # of the watched files
        self.generation = 0  # of the page's requests
        self.layout, self.compare = options.layout, options.compare
        self.changes: dict[str, float] = {}  # slider changes, real units
        self.saved, note = read_saved(options.layouts)
        self.html: str | None = None  # the viewer's page of the last result
        self.info: dict | None = None
        self.state: dict = {"type": "state", "scenario": options.scenario, "busy": True,
                            "error": None, "view": 0, "note": note, "notice": "",
                            "layouts_file": options.layouts, "sweep": None}
        self._context = multiprocessing.get_context("spawn")
        self._shared = self._context.Value("q", 0, lock=False)
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None
        self._pid: int | None = None  # the worker's, once it said
        self._tasks: set[asyncio.Task] = set()
        self._changed_at: float | None = None
        self._sweep_token = None

    # --- the worker -------------------------------------------------------------------------

    def _start_pool(self) -> None:
        self._pool = pool = concurrent.futures.ProcessPoolExecutor(
            1, mp_context=self._context, initializer=worker.init,
            initargs=(self._shared, os.getpid(), self.options.log_level))
        self._pid = None

        def known(future) -> None:
            if self._pool is pool and not future.cancelled() and future.exception() is None:
                self._pid = future.result()

        # the first task starts the worker: it is born with Ctrl-C ignored (an ignored signal
        # stays so across exec, and Python then sets no KeyboardInterrupt handler), so a
        # Ctrl-C while it still imports prints no traceback; the server stops it
        main = threading.current_thread() is threading.main_thread()
        before = signal.signal(signal.SIGINT, signal.SIG_IGN) if main else None
        try:
            pool.submit(worker.hello).add_done_callback(known)
        finally:
            if main:
                signal.signal(signal.SIGINT, before)

    async def _run(self, task, *args) -> dict:
        """``task(*args)`` in the worker. A worker found dead is replaced first; one that
        dies while it works is replaced too, and the page says so in one line."""
        for _ in range(2):
            if self._pool is None:
                self._start_pool()
            try:
                future = self._pool.submit(task, *args)
                break
            except BrokenProcessPool:
                self._pool = None
        try:
            return await asyncio.wrap_future(future)
        except BrokenProcessPool:
            self._pool = None
            return {"error": "rgmcad: error: the simulation worker stopped unexpectedly; a new "
                    "one starts with the next change", "line": None}

    def start(self) -> None:
        self._start_pool()
        self.refresh()

    async def close(self) -> None:
        """Stop the worker (its simulation stops within a few steps; killed after
        :data:`STOP_WITHIN` s, a part build cannot be interrupted) and close the pages."""
        self._shared.value = 2**62
        for ws in list(self.sockets):
            await ws.close()
        pool, self._pool = self._pool, None
        if pool is None:
            return
        stopping = asyncio.ensure_future(asyncio.to_thread(pool.shutdown, True, cancel_futures=True))
        done, _ = await asyncio.wait([stopping], timeout=STOP_WITHIN)
        if not done and self._pid is not None:
            try:
                os.kill(self._pid, signal.SIGKILL)
            except OSError:
                pass
            await stopping

    # --- requests ---------------------------------------------------------------------------

    def request(self) -> worker.Request:
        o = self.options
        extra: dict = {name: doc.get("values", {}) for name, doc in self.saved.items()}
        extra.update({path: path for path in o.files})
        return worker.Request(o.scenario, o.build_dir, o.parts_dir, self.revision,
                              self.generation, self.layout, tuple(self.changes.items()),
                              self.compare, extra)

    def layouts(self) -> list[str]:
        """The layouts a page may choose: the scenario's, the saved ones, the files given."""
        named = (self.info or {}).get("layouts", ["initial"])
        return list(dict.fromkeys([*named, *self.saved, *self.options.files]))

    def files_changed(self, seen_at: float) -> None:
        """The scenario or one of its drawings was saved (``seen_at``: when, perf_counter)."""
        self.revision += 1
        self._changed_at = seen_at if self._changed_at is None else self._changed_at
        self.refresh()

    def refresh(self) -> None:
        """Simulate the current state again; whatever ran before is superseded."""
        self.generation += 1
        self._shared.value = self.generation
        self._spawn(self._view(self.request(), self._changed_at or time.perf_counter()))

    def _spawn(self, coroutine) -> None:
        task = asyncio.get_running_loop().create_task(coroutine)
        self._tasks.add(task)
        task.add_done_callback(self._tasks.discard)

    async def _view(self, req: worker.Request, since: float) -> None:
        self.state.update(busy=True)
        await self.broadcast()
        answer = await self._run(worker.view, req)
        if answer.get("superseded") or req.generation != self.generation:
            return
        self._changed_at = None
        took = time.perf_counter() - since
        if "error" in answer:
            self.state.update(busy=False, error={"text": answer["error"], "line": answer["line"]},
                              took=took)
        else:
            self.html = answer.pop("html")
            self.info = answer["info"]
            self.state.update(busy=False, error=None, took=took, view=self.state["view"] + 1,
                              info=self.info, main=answer["main"], compare=answer["compare"],
                              note=answer["note"], seconds=answer["seconds"])
        self.state.update(generation=req.generation, layout=self.layout,
                          compare_layout=self.compare, layouts=self.layouts())
        log.info("%s in %.3f s", answer.get("error") or answer["main"]["outcome"], took)
        await self.broadcast()

    # --- what the pages send ----------------------------------------------------------------

    async def handle(self, message) -> None:
        """One message of a page: ``set`` a parameter (shown units), choose the ``layout``
        or the one to ``compare`` with, ``sweep`` a parameter, ``save`` the layout."""
        kind = message.get("type") if isinstance(message, dict) else None
        free = {f["name"]: f for f in (self.info or {}).get("free", [])}
        name = message.get("name") if kind else None
        if not (name is None or isinstance(name, str)):
            kind = None  # a list or a table is no name
        if kind == "set" and name in free and _number(message.get("value")):
            self.changes[name] = real(free[name]["unit"], message["value"])
            self.refresh()
        elif kind == "layout" and name in self.layouts():
            self.layout = name
            self.changes.clear()
            self.refresh()
        elif kind == "compare" and (name is None or name in self.layouts()):
            self.compare = name
            self.refresh()
        elif kind == "sweep" and name in free:
            points = message.get("points", SWEEP_POINTS)
            points = int(points) if _number(points) else SWEEP_POINTS
            self._spawn(self._sweep(free[name], min(max(points, 2), MAX_SWEEP_POINTS)))
        elif kind == "save" and isinstance(name, str):
            await self._save(name)
        else:
            await self.notify(f"ignored a message the server does not take: {str(message)[:80]}")

    async def _sweep(self, free: dict, points: int) -> None:
        """Simulate the layout at ``points`` values of one parameter, across its range (the
        other parameters as they are), one point after another; a later change stops it."""
        token = self._sweep_token = object()
        req, sweep = self.request(), {"name": free["name"], "unit": free["unit"], "points": [],
                                      "done": False, "stopped": None, "total": points}
        self.state["sweep"] = sweep
        for value in np.linspace(free["low"], free["high"], points):
            if token is not self._sweep_token:
                return  # a newer sweep took over
            if req.generation != self.generation:
                sweep["stopped"] = "stopped: the layout or the scenario changed; sweep again"
                break
            answer = await self._run(worker.sweep_point, req, free["name"],
                                     real(free["unit"], value))
            if answer.get("superseded"):
                continue  # the check above says why
            if "error" in answer:
                sweep["stopped"] = answer["error"]
                break
            sweep["points"].append({"value": float(value), **answer})
            await self.broadcast()
        sweep["done"] = True
        await self.broadcast()

    async def _save(self, name: str) -> None:
        path = self.options.layouts
        if not LAYOUT_NAME.match(name):
            await self.notify(f"not saved: a layout's name is 1 to 64 letters, digits, '_', '-' "
                              f"or '.', starting with a letter or digit; got {name[:80]!r}")
            return
        answer = await self._run(worker.document, self.request(), name)
        if "document" not in answer:
            await self.notify("not saved: " + answer.get("error", "the layout changed while "
                                                           "saving; save again"))
            return
        try:
            self.saved = await asyncio.to_thread(write_saved, path, name, answer["document"])
        except (OSError, ValueError) as exc:
            await self.notify(f"not saved: {path}: {exc}")
            return
        self.state["layouts"] = self.layouts()
        await self.notify(f"saved layout {name!r} in {path}; `rgmcad simulate SCENARIO "
                          f"--layout {path}` reads it back")

    # --- the pages --------------------------------------------------------------------------

    async def notify(self, text: str) -> None:
        self.state["notice"] = text
        await self.broadcast()
        self.state["notice"] = ""

    async def broadcast(self) -> None:
        """Send the state to every open page (one that went away is forgotten)."""
        for ws in list(self.sockets):
            try:
                await ws.send_json(self.state)
            except (ConnectionError, RuntimeError):
                self.sockets.discard(ws)


def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
