"""What several commands share: the scenario argument, the part cache, layout flags, tables."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


def say(text: str = "") -> None:
    """One line on stdout (the library itself never prints)."""
    sys.stdout.write(text + "\n")


def add_scenario_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="scenario file (TOML), or the name of a shipped scenario "
                   "(e.g. simple)")


def add_layout_args(p: argparse.ArgumentParser, vector: bool = True) -> None:
    group = p.add_mutually_exclusive_group()
    group.add_argument("--layout", help="a named layout of the scenario (default: initial) or a "
                       "layout file (JSON/TOML with `values` or `vector`)")
    if vector:
        group.add_argument("--vector", help="a design vector v1,...,vd in [0, 1]")
    p.add_argument("--value", action="append", default=[], metavar="NAME=V",
                   help="set one free parameter of that layout (repeatable), in the file's units "
                   "(metres, degrees), e.g. track.x=0.12: to sweep a parameter by hand")


def layout_arg(scenario, args) -> tuple[str, np.ndarray]:
    """(name, real values (d,)) of ``--layout``/``--vector`` with ``--value`` changes; the
    name lists the changes (``hand, track.x=0.12``)."""
    from rgmcad.scene.layout_files import resolve_layout

    name, values = resolve_layout(scenario, args.layout, getattr(args, "vector", None))
    return with_values(scenario, name, values, args.value)


def with_values(scenario, name: str, values, pairs) -> tuple[str, np.ndarray]:
    """``values`` with the ``--value NAME=V`` ``pairs`` applied, and the layout's name."""
    import numpy as np

    from rgmcad.errors import UsageError

    index = {f.name: i for i, f in enumerate(scenario.free)}
    values, given = np.array(values, float), set()
    for pair in pairs:
        key, sep, text = (t.strip() for t in pair.partition("="))
        if not sep or key not in index:
            raise UsageError("--value", pair, "expected NAME=V with NAME a free parameter: "
                             + ", ".join(index))
        if key in given:
            raise UsageError("--value", key, "given twice")
        try:
            values[index[key]] = float(text)
        except ValueError:
            raise UsageError("--value", pair, f"expected a number, got {text!r}") from None
        if not np.isfinite(values[index[key]]):
            raise UsageError("--value", pair, f"expected a finite number, got {text!r}")
        _note_far_value(scenario.free[index[key]], values[index[key]])
        given.add(key)
    return ", ".join([name, *pairs]) if pairs else name, values


def _note_far_value(f, value: float) -> None:
    """Warn, in one line naming the key, of a ``--value`` further outside its parameter's
    range than the range is wide (``cup.y=17`` for 17 mm puts the cup 17 m away)."""
    import logging

    width = f.high - f.low
    by = f.low - value if value < f.low else value - f.high
    if by <= width:
        return
    unit = "deg" if f.unit == "deg" else "m"
    slip = (" (millimetres written as metres? --value takes metres and degrees, as the "
            "scenario file)" if unit == "m" and abs(value) >= 1 else "")
    logging.getLogger("rgmcad.cli").warning(
        f"--value {f.name}={value:g} {unit} is {by:g} {unit} outside its range "
        f"[{f.low:g}, {f.high:g}] {unit}{slip}")


def add_scheduler_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--scheduler", metavar="ADDRESS", default=None, type=scheduler_address,
                   help="run the simulations on a Dask cluster: a scheduler's address "
                   "(tcp://host:8786; one that does not answer within 3 s is refused) or "
                   "local:N (N worker processes here); default: $RGMCAD_SCHEDULER, else "
                   "--workers processes; results do not depend on it")


def scheduler_address(text: str) -> str:
    """``type=`` of ``--scheduler``: its form checked as it is parsed (no connection yet)."""
    from rgmcad.errors import UsageError
    from rgmcad.runs.executor import check_scheduler

    try:
        address = check_scheduler(text, "--scheduler")
    except UsageError as exc:
        raise argparse.ArgumentTypeError(f"{exc.key}: {exc.message}") from None
    if not address.startswith("local:"):  # asked now, answered while the command loads
        from rgmcad.runs.dask_executor import ask_scheduler

        ask_scheduler(address)
    return address


def scheduler_from_environment(args) -> None:
    """``$RGMCAD_SCHEDULER`` as ``--scheduler`` of a command that takes it and was not given
    it: checked, and its scheduler asked, as the command starts (one line naming it)."""
    from rgmcad.runs.executor import scheduler_from_env

    if getattr(args, "scheduler", "") is None:
        args.scheduler = scheduler_from_env(None)
        if args.scheduler is not None and not args.scheduler.startswith("local:"):
            from rgmcad.runs.dask_executor import ask_scheduler

            ask_scheduler(args.scheduler)


def parts_dir_arg(args) -> Path | None:
    """The folder of ``--parts DIR`` (None: the shipped part families)."""
    from rgmcad.errors import UsageError

    parts = getattr(args, "parts", None)
    if parts is None:
        return None
    if not Path(parts).is_dir():
        raise UsageError(parts, "--parts", "expected a folder of part family files (*.py)")
    return Path(parts).resolve()


def load_scenario_arg(args):
    """The scenario named by ``args.scenario`` (a file, or a shipped scenario's name), its
    part families from ``--parts DIR`` if given."""
    from rgmcad.scene.loader import load_scenario

    return load_scenario(args.scenario, parts_dir=parts_dir_arg(args))


def load_parts_of(scenario, args) -> dict:
    """Built parts of ``scenario`` from the part cache (``--build-dir``), built if missing."""
    from rgmcad.scene.bodies import load_parts

    note_first_build(args)
    return load_parts(scenario, Path(args.build_dir))


def note_first_build(args) -> None:
    """Say on stderr that parts are about to be built, when the part cache does not exist."""
    if not Path(args.build_dir).exists() and not getattr(args, "quiet", 0):
        print(f"building parts into {args.build_dir} (first run only)...", file=sys.stderr)


def budget_name(name: str) -> str:
    """``--budget``, checked against the library's presets when given (importing the learner
    takes seconds, too long for every command's start)."""
    from rgmcad.learning.settings import BUDGETS

    name = name.lower()
    if name not in BUDGETS:
        raise argparse.ArgumentTypeError(f"unknown budget {name!r}; valid: {', '.join(BUDGETS)}")
    return name


def print_table(rows: list[tuple], headers: tuple) -> None:
    widths = [max(len(str(x)) for x in col) for col in zip(headers, *rows, strict=False)]
    for row in (headers, *rows):
        say("  ".join(str(x).ljust(w) for x, w in zip(row, widths, strict=False)).rstrip())
