"""``reference/cli.md``: every command of ``rgmcad`` and every option, read from the argparse
parser the command line itself uses (:func:`rgmcad.cli.build_parser`)."""

from __future__ import annotations

import argparse

from rgmcad.cli import build_parser
from rgmcad.reference.text import cell, code, prose, sentence, table

WIDTH = 88
"""Columns of the usage lines (argparse would take the terminal's)."""


def commands(parser: argparse.ArgumentParser) -> list[tuple[str, argparse.ArgumentParser, str]]:
    """(name, parser, one-line help) of every command that runs something, in the help's
    order; a command group (``build``) gives its sub-commands (``build parts``)."""
    out = []
    for action in parser._actions:
        if not isinstance(action, argparse._SubParsersAction):
            continue
        helps = {a.dest: a.help for a in action._choices_actions}
        for name, sub in action.choices.items():
            if helps.get(name) == argparse.SUPPRESS:
                continue
            if any(isinstance(a, argparse._SubParsersAction) for a in sub._actions):
                out += commands(sub)
            else:
                out.append((sub.prog.removeprefix("rgmcad").strip(), sub,
                            helps.get(name) or sub.description or ""))
    return out


def options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    """The arguments ``--help`` shows: hidden ones (help suppressed) and sub-commands left out."""
    return [a for a in parser._actions if a.help != argparse.SUPPRESS
            and not isinstance(a, argparse._SubParsersAction)]


def _formatter(parser: argparse.ArgumentParser) -> argparse.HelpFormatter:
    return parser.formatter_class(prog=parser.prog, width=WIDTH)


def _usage(parser: argparse.ArgumentParser) -> str:
    formatter = _formatter(parser)
    formatter.add_usage(parser.usage, parser._actions, parser._mutually_exclusive_groups)
    return f"```text\n{formatter.format_help().strip()}\n```"


def _invocation(formatter: argparse.HelpFormatter, action: argparse.Action) -> str:
    if action.option_strings:
        return formatter._format_action_invocation(action)
    return formatter._format_args(action, action.dest)


def _default(action: argparse.Action) -> str:
    """The default worth saying: none for a flag (it takes no value), a value never set
    (None, suppressed) or an empty list of a repeatable option."""
    value = action.default
    if action.required and action.option_strings:
        return "required"
    if action.nargs == 0 or value in (None, argparse.SUPPRESS, []):
        return ""
    return code(value)


def rows(parser: argparse.ArgumentParser, actions: list[argparse.Action]) -> list[tuple]:
    """(argument, default, help) of each action, the help expanded as ``--help`` does."""
    formatter = _formatter(parser)
    return [(f"`{_invocation(formatter, a)}`", _default(a), formatter._expand_help(a) if a.help
             else "") for a in actions]


def _flags(action: argparse.Action) -> tuple[str, ...]:
    return tuple(action.option_strings) or (action.dest,)


def page(parser: argparse.ArgumentParser | None = None) -> str:
    parser = build_parser() if parser is None else parser
    top = options(parser)
    found = commands(parser)
    # the options of rgmcad itself that every command takes too (after its name)
    shared = [a for a in top if all(_flags(a) in {_flags(b) for b in options(p)}
                                     for _, p, _ in found)]
    shared_flags = {_flags(a) for a in shared}
    out = ["# Command line", "",
           "Every command and option of `rgmcad`, generated from the parser the command line "
           "uses, so it says what `rgmcad COMMAND --help` says. Give a scenario as a file or as "
           "the name of a shipped scenario.", "",
           "## Global options {#global-options}", "",
           cell(parser.description or ""), "", _usage(parser), "",
           "Options of `rgmcad` itself, given before the command. "
           + (", ".join(f"`{a.option_strings[-1]}`" for a in shared)
              + " may also come after it: every command takes them." if shared else ""), "",
           table(["option", "default", "what it does"], rows(parser, top)), "",
           "## Commands", "",
           table(["command", "what it does"],
                 [(f"[`rgmcad {name}`](#{_anchor(name)})", line) for name, _, line in found]), ""]
    for name, sub, line in found:
        own = [a for a in options(sub) if _flags(a) not in shared_flags]
        out += [f"## rgmcad {name} {{#{_anchor(name)}}}", "", cell(sentence(line)), "",
                _usage(sub), "",
                table(["argument", "default", "what it does"], rows(sub, own)) if own
                else "No arguments of its own.", ""]
        if sub.epilog:
            out += [prose(sub.epilog), ""]
        if shared:
            out += [f"It takes the [global options](#global-options) "
                    f"{', '.join(f'`{a.option_strings[-1]}`' for a in shared)} too.", ""]
    return "\n".join(out)


def _anchor(name: str) -> str:
    return name.replace(" ", "-")
