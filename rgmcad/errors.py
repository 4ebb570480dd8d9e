"""Errors for input a user can fix. Each names where (a file or a flag), the key and what is
allowed, in one line: ``str(error)`` is ``<where>: <key>: <message>``. The CLI prints it and
exits with status 2, whatever the kind.

Kinds, by the stage that raises them: :class:`ScenarioError` (a scenario, layout or part
file), :class:`PartBuildError` (a part family whose CAD build fails), :class:`RunDirectoryError`
(a run directory made for another run, or in use), :class:`PrintCheckError` (an image that
cannot be read or holds no marks) and :class:`UsageError` (a command-line flag).

Text read from a file reaches a terminal only through :func:`printable`: an error's parts
are escaped when it is made, so a file cannot move the cursor, retitle the window or clear
the screen by what it quotes.
"""

import unicodedata


def printable(text: str) -> str:
    """``text`` with every character that is not printable escaped as Python writes it in a
    string (``\\x1b``, ``\\n``, ``\\x9b``, ``\\u202e``): C0 and C1 controls, DEL, line breaks,
    tabs, format characters (bidirectional overrides, zero-width joiners), surrogates and
    unassigned code points. Spaces of every width stay. The result is one line."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or unicodedata.category(c) == "Zs"
                   else repr(c)[1:-1] for c in text)


class RgmcadError(ValueError):
    """Bad input: ``<where>: <key>: <message>``, one line, each part :func:`printable`."""

    def __init__(self, where: str, key: str, message: str):
        self.where, self.key, self.message = (printable(str(where)), printable(str(key)),
                                              printable(str(message)))
        parts = [p for p in (self.where, self.key) if p]
        super().__init__(": ".join([*parts, self.message]))


def error_line(exc: RgmcadError) -> str:
    """What ``rgmcad`` prints for ``exc`` (and the live page shows): one line."""
    return f"rgmcad: error: {' '.join(str(exc).splitlines())}"


class ScenarioError(RgmcadError):
    """Bad input in a scenario, layout or part file."""


class PartBuildError(RgmcadError):
    """A part family's CAD build failed or gave an unusable solid."""


class RunDirectoryError(RgmcadError):
    """A run directory that this run cannot use."""


class PrintCheckError(RgmcadError):
    """A scan or photo that cannot be checked."""


class UsageError(RgmcadError):
    """A bad command-line flag or argument."""
