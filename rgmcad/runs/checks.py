"""Checks of what a run is asked to use, made before any simulation: numbers in their range,
and places it will write to. Each failure is a :class:`~rgmcad.errors.UsageError` of one line
naming the flag (or parameter) and what is allowed, so a mistake costs no simulation time.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from rgmcad.errors import UsageError
from rgmcad.runs.executor import max_workers

__all__ = ["MAX_SEED", "MAX_SAMPLES", "MAX_BATCH", "check_range", "check_workers", "check_output_file",
           "check_plot_file", "plot_suffixes"]

MAX_SEED = 2**32 - 1
"""Seeds are 0..2^32 - 1 (what every numpy generator accepts and a run's name can show)."""

MAX_SAMPLES = 100_000
"""Layouts per radius of ``evaluate``: 30 radii of 100 000 is three million simulations."""

MAX_BATCH = 10_000
"""Most simulations in one exploration batch (``optimize --batch``)."""


def check_range(value, low: int, high: int, where: str, what: str) -> int:
    """``value`` as an int in ``[low, high]``, or UsageError naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise UsageError(where, "", f"expected {what} from {low} to {high}, got {value!r}")
    return value


def check_workers(workers: int | None, where: str = "--workers") -> int | None:
    """``workers`` (None: every CPU) checked against 1..:func:`max_workers`."""
    if workers is None:
        return None
    return check_range(workers, 1, max_workers(), where,
                       f"a number of worker processes (4 per CPU, {os.cpu_count()} CPUs here)")


def check_output_file(path: str | Path, where: str) -> Path:
    """``path`` is a file this process can write: its folder exists (as for every command's
    output files, see ``rgmcad/cli/paths.py``), is a folder and takes a new file (tried: root
    passes ``os.access`` even on a read-only folder), and ``path`` is not a folder and, if it
    exists, opens for writing. Nothing is left behind."""
    if "\0" in str(path):
        raise UsageError(where, repr(str(path)), "not a usable path")
    path = Path(path)
    folder = path.parent
    if path.is_dir():
        raise UsageError(where, str(path), "is a directory; expected a file name")
    if not folder.is_dir():
        raise UsageError(where, str(path), f"{str(folder)!r} " + (
            "is not a folder" if folder.exists() else "does not exist") + "; expected a file "
            "in an existing folder")
    try:
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".rgmcad-write-test-"):
            pass
        if path.exists():
            with open(path, "ab"):
                pass
    except OSError as exc:
        raise UsageError(where, str(path), f"cannot write here ({exc.strerror or exc}); choose "
                         "another place") from None
    return path


def plot_suffixes() -> tuple[str, ...]:
    """The extensions matplotlib can write (``.png``, ``.pdf``, ``.svg``, ...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(f".{f}" for f in sorted(FigureCanvasBase.get_supported_filetypes()))


def check_plot_file(path: str | Path, where: str) -> Path:
    """:func:`check_output_file`, and a name whose extension matplotlib can write (none: PNG)."""
    suffix = Path(path).suffix.lower()
    if suffix and suffix not in plot_suffixes():
        raise UsageError(where, str(path), f"cannot draw a {suffix} file; use one of "
                         f"{', '.join(plot_suffixes())}")
    return check_output_file(path, where)
