"""Errors for input a user can fix. Each names where (a file or a flag), the key and what is
allowed, in one line: ``str(error)`` is ``<where>: <key>: <message>``. The CLI prints it and
exits with status 2, whatever the kind.

Kinds, by the stage that raises them: :class:`ScenarioError` (a scenario, layout or part
file), :class:`PartBuildError` (a part family whose CAD build fails), :class:`RunDirectoryError`
(a run directory made for another run, or in use), :class:`PrintCheckError` (an image that
cannot be read or holds no marks) and :class:`UsageError` (a command-line flag).
"""


class RgmcadError(ValueError):
    """Bad input: ``<where>: <key>: <message>``, one line."""

    def __init__(self, where: str, key: str, message: str):
        self.where, self.key, self.message = str(where), key, message
        parts = [p for p in (self.where, key) if p]
        super().__init__(": ".join([*parts, message]))


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
