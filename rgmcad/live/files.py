"""The files of the live page: those it watches (the scenario and the SVG drawings its domino
runs follow) and the layout file its Save button writes.

The layout file is a layout file as every command reads it (``--layout FILE``,
:func:`~rgmcad.scene.layout_files.load_layout_file`): its top level is the layout saved last
(:func:`~rgmcad.scene.layout_files.layout_document`, with its ``name``), and ``layouts``
keeps every layout saved into it by name, which the page offers again.
"""

from __future__ import annotations

import json
import os
import time
import tomllib
from collections.abc import Callable
from pathlib import Path

from watchdog.events import (
    EVENT_TYPE_CLOSED,
    EVENT_TYPE_CREATED,
    EVENT_TYPE_DELETED,
    EVENT_TYPE_MODIFIED,
    EVENT_TYPE_MOVED,
    FileSystemEventHandler,
)
from watchdog.observers import Observer

from rgmcad.files import write_json_atomic

__all__ = ["scenario_text", "watched_files", "Watcher", "read_saved", "write_saved"]

_WRITES = {EVENT_TYPE_MODIFIED, EVENT_TYPE_CREATED, EVENT_TYPE_MOVED, EVENT_TYPE_DELETED,
           EVENT_TYPE_CLOSED}
"""Events that change a file (opening or reading one, as the worker does, is none)."""


def scenario_text(scenario: str | Path) -> str | None:
    """A scenario (or layout) file's text, read as the loader reads it (sized first, at most
    ``MAX_FILE_BYTES``: a huge file costs nothing); None when it cannot be read so."""
    from rgmcad.scene.loader_checks import FileRefused, read_limited
    from rgmcad.scene.schema import MAX_FILE_BYTES

    try:
        return read_limited(scenario, MAX_FILE_BYTES).decode("utf-8")
    except (OSError, FileRefused, UnicodeDecodeError):
        return None


def watched_files(scenario: str | Path) -> set[Path]:
    """The scenario file and the SVG files its runs' paths name (``path = { kind = "svg",
    file = ... }``, found beside the scenario as the loader finds them), real paths."""
    scenario = Path(scenario)
    files = {scenario}
    try:
        data = tomllib.loads(scenario_text(scenario) or "")
    except (tomllib.TOMLDecodeError, RecursionError):
        data = {}
    runs = data.get("runs")
    for run in runs.values() if isinstance(runs, dict) else ():
        path = run.get("path") if isinstance(run, dict) else None
        if isinstance(path, dict) and path.get("kind") == "svg" and isinstance(path.get("file"), str):
            files.add(scenario.parent / path["file"])
    return {Path(os.path.realpath(f)) for f in files}


class _Handler(FileSystemEventHandler):
    def __init__(self, watcher: Watcher):
        self.watcher = watcher

    def on_any_event(self, event) -> None:
        if event.event_type not in _WRITES:
            return
        paths = {event.src_path, getattr(event, "dest_path", "") or event.src_path}
        if any(Path(os.fsdecode(p)) in self.watcher.files for p in paths):
            self.watcher.changed(time.perf_counter())


class Watcher:
    """Calls ``changed(when)`` (from its own thread) when a watched file is written, created,
    replaced (an editor's save by renaming) or deleted. The folders of the files are watched,
    not the files, so a file replaced by another is still followed."""

    def __init__(self, changed: Callable[[float], None]):
        self.changed = changed
        self.files: frozenset[Path] = frozenset()
        self._observer = Observer()
        self._observer.daemon = True
        self._folders: dict[Path, object] = {}
        self._handler = _Handler(self)

    def watch(self, files: set[Path]) -> None:
        """Watch exactly ``files`` from now on."""
        self.files = frozenset(files)
        folders = {f.parent for f in files if f.parent.is_dir()}
        for folder in set(self._folders) - folders:
            self._observer.unschedule(self._folders.pop(folder))
        for folder in folders - set(self._folders):
            self._folders[folder] = self._observer.schedule(self._handler, str(folder),
                                                            recursive=False)

    def start(self) -> None:
        self._observer.start()

    def stop(self) -> None:
        self._observer.stop()
        self._observer.join(timeout=5)


def read_saved(path: str | Path) -> tuple[dict[str, dict], str]:
    """The layouts saved in the layout file ``path`` by name, and a note when the file
    exists but holds none that can be read (it is then left alone until a save)."""
    path = Path(path)
    if not path.exists():
        return {}, ""
    text = scenario_text(path)  # a layout file has the scenario file's size limit
    try:
        data = json.loads(text) if text is not None else None
    except (ValueError, RecursionError) as exc:
        return {}, f"{path}: not read as a layout file ({type(exc).__name__})"
    if text is None:
        return {}, f"{path}: not read as a layout file (too large, or not a UTF-8 file)"
    layouts = data.get("layouts") if isinstance(data, dict) else None
    if not isinstance(layouts, dict):
        return {}, ""
    return {str(k): v for k, v in layouts.items()
            if isinstance(v, dict) and isinstance(v.get("values"), dict)}, ""


def write_saved(path: str | Path, name: str, document: dict) -> dict[str, dict]:
    """Save ``document`` (a layout file's data) as layout ``name`` in the layout file ``path``:
    it becomes the file's top level, and joins the layouts kept under ``layouts``. The file
    is replaced whole (written beside it, then renamed). Returns the saved layouts.

    Raises ValueError for an existing file that is not a layout file (it is not overwritten).
    """
    path = Path(path)
    old: dict = {}
    if path.exists():
        try:
            old = json.loads(scenario_text(path) or "")
        except (ValueError, RecursionError):
            raise ValueError("exists and is not a JSON layout file; left as it is") from None
        if not isinstance(old, dict) or ("values" not in old and "vector" not in old
                                         and "layouts" not in old):
            raise ValueError("exists and is not a layout file; left as it is")
    kept = old.get("layouts") if isinstance(old.get("layouts"), dict) else {}
    layouts = {**kept, name: document}
    write_json_atomic(path, {**document, "layouts": layouts})
    return layouts
