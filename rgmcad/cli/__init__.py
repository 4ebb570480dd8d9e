"""The ``rgmcad`` command line: a thin layer over the library.

Commands come from one table (:data:`COMMANDS`): each names the module of ``rgmcad.cli`` that
configures its arguments (``configure``) and runs it (``run``: load, one library call, print).
Command modules import the library inside ``run``, so the CLI starts fast. Every error of
:mod:`rgmcad.errors` prints one line naming the file or flag, the key and what is allowed, and
exits with status 2.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from rgmcad.errors import RgmcadError
from rgmcad.parts.store import DEFAULT_BUILD_DIR

COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("simulate", "simulate one layout and print the event timeline"),
    "check": ("check", "validate a scenario file and summarise it"),
    "render": ("render", "draw a layout to a PNG"),
    "build parts": ("build_parts",
                    "build the parts of the shipped scenarios (STEP, STL, GLB, collision pieces)"),
    "template": ("template",
                 "write a printable 1:1 tiled assembly template (PDF and SVG) of a layout"),
    "verify-print": ("verify_print",
                     "measure the scale a template sheet was printed at, from a scan or photo"),
    "optimize": ("optimize",
                 "learn the success probability and optimise a robust layout (resumable run)"),
    "evaluate": ("evaluate", "measure a layout's local and global robustness by simulation"),
}
"""Command -> (module of rgmcad.cli, help). Multi-word commands are sub-commands."""

def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rgmcad", description="Design chain-reaction "
                                     "contraptions that work when built by hand.")
    parser.add_argument("--build-dir", default=str(DEFAULT_BUILD_DIR),
                        help=f"where built parts are cached (default: {DEFAULT_BUILD_DIR})")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    groups: dict[str, argparse._SubParsersAction] = {}
    for name, (module_name, help_text) in COMMANDS.items():
        words = name.split()
        if len(words) == 1:
            p = sub.add_parser(name, help=help_text, description=help_text)
        else:  # multi-word commands: "build parts"
            if words[0] not in groups:
                g = sub.add_parser(words[0], help=f"{words[0]} ...")
                groups[words[0]] = g.add_subparsers(dest="subcommand", required=True,
                                                    metavar="WHAT")
            p = groups[words[0]].add_parser(words[1], help=help_text, description=help_text)
        # command modules import the library inside ``run``: importing them all is cheap
        module = importlib.import_module(f"rgmcad.cli.{module_name}")
        module.configure(p)
        p.set_defaults(run=module.run)
    return parser


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s")
    args = build_parser().parse_args(argv)
    if hasattr(args, "scenario"):
        from rgmcad.shipped import scenario_path

        args.scenario = str(scenario_path(args.scenario))
    try:
        return args.run(args)
    except RgmcadError as exc:
        print(f"rgmcad: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rgmcad: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
