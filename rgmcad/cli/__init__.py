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
import os
import sys

from rgmcad.cli.common import scheduler_from_environment
from rgmcad.cli.parser import Parser, add_global_options
from rgmcad.cli.paths import default_build_dir, output_dir
from rgmcad.errors import RgmcadError, error_line

COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("simulate", "simulate one layout and print the event timeline"),
    "check": ("check", "validate a scenario file and summarise it"),
    "render": ("render", "draw a layout to a PNG"),
    "build parts": ("build_parts",
                    "build the parts of the shipped scenarios (STEP, STL, GLB, collision pieces)"),
    "template": ("template",
                 "write a printable 1:1 tiled assembly template (PDF and SVG) of a layout"),
    "supports": ("supports", "design stands for a layout's raised static parts, clear of the "
                 "moving parts' paths (STL, STEP, card nets)"),
    "verify-print": ("verify_print",
                     "measure the scale a template sheet was printed at, from a scan or photo"),
    "optimize": ("optimize",
                 "learn the success probability and optimise a robust layout (resumable run)"),
    "evaluate": ("evaluate", "measure a layout's local and global robustness by simulation"),
    "benchmark": ("benchmark", "compare our method with the paper's baselines and CMA-ES "
                  "(a table like Table 1, resumable)"),
    "export": ("export", "write a posed layout as one CAD assembly (STEP in mm, or GLB)"),
    "live": ("live", "serve a live page of a scenario that simulates it again on every save, "
             "with sliders, a sweep and layouts side by side"),
}
"""Command -> (module of rgmcad.cli, help). Multi-word commands are sub-commands."""


def build_parser() -> argparse.ArgumentParser:
    import shtab

    from rgmcad import __version__

    parser = Parser(prog="rgmcad", description="Design chain-reaction "
                    "contraptions that work when built by hand.")
    parser.add_argument("--version", action="version", version=f"rgmcad {__version__}")
    shtab.add_argument_to(parser, "--print-completion", help="print a shell completion "
                          "script (bash, zsh or tcsh) on stdout")
    add_global_options(parser, {"build_dir": None, "parts": None, "verbose": 0, "quiet": 0})
    parser.commands = {}
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
        add_global_options(p, None)
        parser.commands[name] = p
        p.set_defaults(run=module.run, uses_build_dir=getattr(module, "USES_BUILD_DIR", True))
    return parser


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # --help, --version
            return exc.code if isinstance(exc.code, int) else 0
        level = logging.WARNING + 10 * (args.quiet - args.verbose)
        logging.getLogger().setLevel(min(max(level, logging.DEBUG), logging.CRITICAL))
        if args.build_dir is None:
            args.build_dir = str(default_build_dir())
        if args.uses_build_dir:  # a folder this command may write: checked before the work
            output_dir(args.build_dir, "--build-dir", writable=False)
        scheduler_from_environment(args)  # $RGMCAD_SCHEDULER: checked as --scheduler is
        if hasattr(args, "scenario"):
            from rgmcad.shipped import scenario_path

            args.scenario_given = args.scenario  # as the user wrote it, for what we print
            args.scenario = str(scenario_path(args.scenario))
        return args.run(args)
    except RgmcadError as exc:
        print(error_line(exc), file=sys.stderr)
        return 2
    except BrokenPipeError:  # whoever read stdout stopped (`rgmcad ... | head`): no traceback
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141
    except OSError as exc:  # a full or read-only disk under an output (files named by rgmcad.files)
        from rgmcad.files import STORAGE_ERRORS, cannot_write

        if exc.errno not in STORAGE_ERRORS:
            raise
        print(f"rgmcad: error: {exc.filename or 'an output file'}: {cannot_write(exc)}",
              file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rgmcad: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
