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

from rgmcad.cli.paths import output_dir
from rgmcad.errors import RgmcadError, UsageError
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
    "benchmark": ("benchmark", "compare our method with the paper's baselines and CMA-ES "
                  "(a table like Table 1, resumable)"),
}
"""Command -> (module of rgmcad.cli, help). Multi-word commands are sub-commands."""


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors (unknown flag, missing or bad value, bad choice) are
    one :class:`UsageError` line, not the usage text; sub-parsers are of this class too."""

    def error(self, message: str):
        command = self.prog.removeprefix("rgmcad").strip()
        raise UsageError(command, "", f"{' '.join(message.split())} (see {self.prog} --help)")

    def parse_args(self, args=None, namespace=None):
        args, extra = self.parse_known_args(args, namespace)
        if extra:  # named with the (sub-)command they were given to
            words = [w for w in (getattr(args, "command", None),
                                 getattr(args, "subcommand", None)) if w]
            Parser(prog=" ".join(["rgmcad", *words])).error(
                f"unrecognized arguments: {' '.join(extra)}")
        return args


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="rgmcad", description="Design chain-reaction "
                    "contraptions that work when built by hand.")
    parser.add_argument("--build-dir", default=str(DEFAULT_BUILD_DIR),
                        help=f"where built parts are cached (default: {DEFAULT_BUILD_DIR})")
    parser.add_argument("--parts", metavar="DIR", default=None,
                        help="the folder of part families to use instead of the shipped ones; "
                        "its Python files are imported (run), like installing a package")
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
        p.set_defaults(run=module.run, uses_build_dir=getattr(module, "USES_BUILD_DIR", True))
    return parser


def main(argv: list[str] | None = None) -> int:
    logging.basicConfig(level=logging.WARNING, format="%(levelname)s: %(message)s")
    try:
        try:
            args = build_parser().parse_args(argv)
        except SystemExit as exc:  # --help
            return exc.code if isinstance(exc.code, int) else 0
        if args.uses_build_dir:  # a folder this command may write: checked before the work
            output_dir(args.build_dir, "--build-dir", writable=False)
        if hasattr(args, "scenario"):
            from rgmcad.shipped import scenario_path

            args.scenario = str(scenario_path(args.scenario))
        return args.run(args)
    except RgmcadError as exc:
        print(f"rgmcad: error: {' '.join(str(exc).splitlines())}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("rgmcad: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
