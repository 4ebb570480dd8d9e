"""The reference section of the documentation site, generated from the code so it is never
written twice: the command line from its parser, scenario keys from the loader and the schema,
events from their registry, part families from their files, run files from the names the code
writes them under. Each page is a markdown string; ``docs/hooks.py`` adds them to the MkDocs
build (``python -m rgmcad.reference`` prints them as JSON)."""

from __future__ import annotations

from collections.abc import Callable

from rgmcad.reference import cli, parts, runs, scenario

PAGES: dict[str, Callable[[], str]] = {
    "reference/cli.md": cli.page,
    "reference/scenario.md": scenario.page,
    "reference/events.md": scenario.events_page,
    "reference/parts.md": parts.page,
    "reference/run-directory.md": runs.page,
}
"""Path in the site's docs folder -> the function that writes the page."""


def pages() -> dict[str, str]:
    return {path: make() for path, make in PAGES.items()}
