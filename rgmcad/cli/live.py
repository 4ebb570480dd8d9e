"""``rgmcad live``: serve a live page of a scenario (3D replay, events, sliders, side by side,
sweep) that follows every save of the file, until Ctrl-C. A scenario that cannot load at the
start is refused in one line (status 2), as by every command; later errors show on the page."""

from __future__ import annotations

import os
import sys
from pathlib import Path

from rgmcad.cli.common import add_scenario_arg, load_scenario_arg, parts_dir_arg, say
from rgmcad.cli.paths import whole_number

DEFAULT_PORT = 8767


port_number = whole_number(0, 65535, "a port from 0 (a free one) to 65535")
"""``type=`` of ``--port``: 0 (a free port) to 65535."""


def configure(p) -> None:
    add_scenario_arg(p)
    p.add_argument("--layout", default="initial", help="the layout shown first: a named layout "
                   "of the scenario (default: initial) or a layout file")
    p.add_argument("--compare", metavar="LAYOUT", help="show this layout beside it from the "
                   "start, one camera and one clock for both: a named layout or a layout file "
                   "such as runs/NAME/layout.json (the page offers the named layouts, the saved "
                   "ones and the files given here)")
    p.add_argument("--layouts", metavar="FILE", help="the layout file (JSON) the page's Save "
                   "button writes named layouts into, read back by --layout FILE of any command "
                   "(default: NAME.layouts.json beside the scenario file, or in the current "
                   "folder for a shipped scenario given by its name)")
    p.add_argument("--host", default="127.0.0.1", help="the address to listen on (default "
                   "127.0.0.1: this machine only; 0.0.0.0 lets other machines in, unprotected)")
    p.add_argument("--port", type=port_number, default=DEFAULT_PORT, help="the port to listen "
                   f"on (default {DEFAULT_PORT}; 0: a free one, printed)")
    p.add_argument("--no-browser", action="store_true", help="print the page's address "
                   "without opening it in a browser")


def _layouts_file(args, scenario) -> str:
    """``--layouts``, else NAME.layouts.json beside the scenario (in the current folder for a
    shipped scenario given by name); never the scenario file itself."""
    from rgmcad.errors import UsageError

    given = Path(args.scenario_given)
    if args.layouts:
        path = Path(args.layouts)
    elif given.exists():
        path = Path(args.scenario).with_name(f"{scenario.name}.layouts.json")
    else:
        path = Path(f"{scenario.name}.layouts.json")
    if path.suffix.lower() != ".json":
        raise UsageError(str(path), "--layouts", "expected a .json file")
    if path.exists() and (path.is_dir() or path.resolve() == Path(args.scenario).resolve()):
        raise UsageError(str(path), "--layouts", "expected a layout file (JSON), not the scenario "
                         "or a folder: the scenario file is never written")
    if not path.parent.is_dir() or not os.access(path.parent, os.W_OK):
        raise UsageError(str(path), "--layouts", "its folder does not exist or cannot be written")
    return str(path)


def _layout_files(scenario, names) -> tuple[str, ...]:
    """The layout files among ``--layout`` and ``--compare``, read once here so that a bad one
    is refused in one line now rather than on the page."""
    from rgmcad.scene.layout_files import resolve_layout

    files = []
    for name in names:
        if name is not None and name not in scenario.layouts:
            resolve_layout(scenario, name, None)
            files.append(name)
    return tuple(files)


def _open(url: str) -> bool:
    """Open ``url`` in the desktop's browser; False where there is no desktop (a text-mode
    browser would take over the terminal the server prints to)."""
    import webbrowser

    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY")
                                                 or os.environ.get("WAYLAND_DISPLAY")):
        return False
    try:
        return webbrowser.open(url)
    except webbrowser.Error:
        return False


def run(args) -> int:
    import logging

    from rgmcad.live import LiveOptions, serve

    scenario = load_scenario_arg(args)
    parts = parts_dir_arg(args)
    options = LiveOptions(
        scenario=args.scenario, build_dir=str(args.build_dir), layouts=_layouts_file(args, scenario),
        parts_dir=None if parts is None else str(parts), layout=args.layout, compare=args.compare,
        files=_layout_files(scenario, (args.layout, args.compare)), host=args.host, port=args.port,
        log_level=logging.getLogger().level)

    def ready(url: str) -> None:
        say(f"{scenario.name}: live page at {url} (Ctrl-C stops)")
        if not args.no_browser and not _open(url):
            say("no browser opened here: open the address above in one")
        sys.stdout.flush()

    try:
        serve(options, ready)
    except KeyboardInterrupt:
        pass
    say("stopped")
    return 0
