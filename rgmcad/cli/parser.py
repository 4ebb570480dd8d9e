"""The argument parser's manners: one-line errors with a "did you mean", choices in any case,
and the global options (``--build-dir``, ``--parts``, ``-v``/``-q``) accepted before or after
the command."""

from __future__ import annotations

import argparse
import difflib
import re
import sys

from rgmcad.errors import UsageError


def _suggest(word: str, choices) -> str:
    by_lower = {c.lower(): c for c in choices}
    close = difflib.get_close_matches(word.lower(), list(by_lower), n=1, cutoff=0.6)
    return f"; did you mean {by_lower[close[0]]}?" if close else ""


def _any_case(choices: tuple[str, ...]):
    """``type=`` of a choice given in any case (``--paper A4``), returned as written in
    ``choices``; an unknown word is left for argparse to refuse with the list."""
    by_lower = {c.lower(): c for c in choices}

    def parse(text: str) -> str:
        return by_lower.get(text.lower(), text)

    return parse


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors (unknown command or flag, missing or bad value, bad
    choice) are one :class:`UsageError` line with the closest valid word, not the usage
    text; sub-parsers are of this class too."""

    def add_argument(self, *names, **kwargs):
        choices = kwargs.get("choices")
        if (choices is not None and kwargs.get("type") is None
                and all(isinstance(c, str) for c in choices)):
            kwargs["type"] = _any_case(tuple(choices))
        return super().add_argument(*names, **kwargs)

    def error(self, message: str):
        command = self.prog.removeprefix("rgmcad").strip()
        message = " ".join(message.split())
        bad = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if bad:
            message += _suggest(bad.group(1), re.findall(r"'([^']*)'", bad.group(2)))
        raise UsageError(command, "", f"{message} (see {self.prog} --help)")

    def flags(self) -> list[str]:
        return [s for a in self._actions for s in a.option_strings]

    def parse_args(self, args=None, namespace=None):
        self._unknown_before_command(sys.argv[1:] if args is None else list(args))
        args, extra = self.parse_known_args(args, namespace)
        if extra:  # named with the (sub-)command they were given to
            words = [w for w in (getattr(args, "command", None),
                                 getattr(args, "subcommand", None)) if w]
            given = self.commands.get(" ".join(words), self) if words else self
            hint = ""
            flag = next((w.split("=")[0] for w in extra if w.startswith("--")), None)
            if flag is not None:
                hint = _suggest(flag, given.flags())
            Parser(prog=" ".join(["rgmcad", *words])).error(
                f"unrecognized arguments: {' '.join(extra)}{hint}")
        self._no_blank_values(args)
        return args

    def _no_blank_values(self, args) -> None:
        """An empty or blank value (``--html ""``, ``--start " "``) is no file, layout or
        address: refused naming its flag, not taken as "none given" or as the folder ``.``."""
        words = [w for w in (getattr(args, "command", None), getattr(args, "subcommand", None)) if w]
        given = self.commands.get(" ".join(words), self) if words else self
        for parser in dict.fromkeys([given, self]):
            for action in parser._actions:
                value = getattr(args, action.dest, None) if action.dest else None
                values = value if isinstance(value, list) else [value]
                if value is not action.default and any(
                        isinstance(v, str) and not v.strip() for v in values):
                    name = action.option_strings[-1] if action.option_strings else action.dest
                    what = action.metavar or action.dest.upper()
                    parser.error(f"argument {name}: expected {what}, got an empty value")

    def _unknown_before_command(self, words: list[str]) -> None:
        """An unknown option before the command would make its value read as the command
        (``rgmcad --buld-dir x check``: "invalid choice: 'x'"): name the option instead."""
        known = self.flags()
        for word in words:
            if not word.startswith("-"):
                return
            flag = word.split("=")[0]
            if word.startswith("--") and not any(k.startswith(flag) for k in known):
                self.error(f"unrecognized arguments: {flag}{_suggest(flag, known)}")

    commands: dict[str, Parser] = {}


def add_global_options(p: argparse.ArgumentParser, defaults: dict | None) -> None:
    """The options every command takes, before or after its name; ``defaults`` None: a
    command's copy, which leaves the value given before the command alone."""

    def default(name):
        return argparse.SUPPRESS if defaults is None else defaults[name]

    p.add_argument("--build-dir", default=default("build_dir"), metavar="DIR",
                   help="where built parts are cached (default: $RGMCAD_CACHE, else "
                   "rgmcad/parts in the user's cache folder)")
    p.add_argument("--parts", metavar="DIR", default=default("parts"),
                   help="the folder of part families to use instead of the shipped ones; "
                   "its Python files are imported (run), like installing a package")
    p.add_argument("-v", "--verbose", action="count", default=default("verbose"),
                   help="say more (-vv: debugging detail)")
    p.add_argument("-q", "--quiet", action="count", default=default("quiet"),
                   help="say less: no progress bars or notes, errors only")
