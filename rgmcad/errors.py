"""The one error type for bad input files: it names the file, the key and what is allowed."""


class ScenarioError(ValueError):
    """Bad input in a scenario, layout or part file.

    ``str(error)`` is one line: ``<file>: <key>: <message>``.
    """

    def __init__(self, where: str, key: str, message: str):
        self.where, self.key, self.message = str(where), key, message
        parts = [p for p in (self.where, key) if p]
        super().__init__(": ".join([*parts, message]))
