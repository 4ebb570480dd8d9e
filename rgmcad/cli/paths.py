"""What a command writes, and how large, checked before any work: sizes in pixels and finite
numbers (``type=`` of an argument, so argparse reports them), output files (their folder
exists, their extension is one the command writes) and output folders (created with missing
parents, as before, unless a file stands in the way). Each problem is one
:class:`~rgmcad.errors.UsageError` naming the flag and what is allowed. (Files a command
reads are checked by their readers: :mod:`rgmcad.scene.loader`, :mod:`rgmcad.printing.check`.)"""

from __future__ import annotations

import argparse
import math
import os
from pathlib import Path

from rgmcad.errors import UsageError

CACHE_VARIABLE = "RGMCAD_CACHE"


def default_build_dir() -> Path:
    """Where built parts are cached unless ``--build-dir`` says: ``$RGMCAD_CACHE``, else
    ``rgmcad/parts`` in the user's cache folder (``$XDG_CACHE_HOME``, by default
    ``~/.cache``, on Linux; ``~/Library/Caches`` on macOS; ``%LOCALAPPDATA%`` on Windows),
    so every working directory shares one cache."""
    if os.environ.get(CACHE_VARIABLE):
        return Path(os.environ[CACHE_VARIABLE])
    from platformdirs import user_cache_path

    return user_cache_path("rgmcad", appauthor=False) / "parts"


def whole_number(low: int, high: int, what: str = "a whole number from {low} to {high}"):
    """``type=`` of a whole number from ``low`` to ``high``; ``what`` says what is allowed."""
    allowed = what.format(low=low, high=high)

    def parse(text: str) -> int:
        try:
            n = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}") from None
        if not low <= n <= high:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}")
        return n

    return parse


def pixels(low: int, high: int):
    """``type=`` of a size in pixels: a whole number from ``low`` to ``high``."""
    return whole_number(low, high, "a whole number of pixels from {low} to {high}")


def finite(text: str) -> float:
    """``type=`` of a finite number (``float`` alone takes ``nan`` and ``inf``)."""
    try:
        x = float(text)
    except ValueError:
        x = math.nan
    if not math.isfinite(x):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return x


def output_file(path: str, flag: str, suffixes: tuple[str, ...]) -> Path:
    """A file a command will write: its name ends in one of ``suffixes``, it is not a folder,
    and its folder exists and can be written."""
    allowed = f"expected a {' or '.join(suffixes)} file in an existing folder"
    p = Path(path)
    _plain(path, flag, allowed)
    try:
        if p.is_dir():
            raise UsageError(path, flag, f"is a folder; {allowed}")
        if p.suffix.lower() not in suffixes:
            raise UsageError(path, flag, f"unsupported extension {p.suffix or '(none)'!r}; "
                             f"{allowed}")
        folder = p.parent
        if not folder.is_dir():
            _blocker(path, flag, folder, allowed)
            raise UsageError(path, flag, f"the folder {folder} does not exist; {allowed}")
        if not os.access(folder, os.W_OK | os.X_OK) or (p.exists() and not os.access(p, os.W_OK)):
            raise UsageError(path, flag, f"cannot write here; {allowed}")
    except OSError as exc:
        raise UsageError(path, flag, f"unusable path ({exc.strerror}); {allowed}") from None
    return p


def output_dir(path: str, flag: str, files: tuple[str, ...] = (), writable: bool = True) -> Path:
    """A folder a command writes into (``files`` are the names it writes there): a folder, or
    missing and creatable (missing parents are created); ``writable=False`` lets an existing
    folder be read-only (a part cache already built)."""
    allowed = "expected a folder (created if missing)"
    p = Path(path)
    _plain(path, flag, allowed)
    try:
        if p.is_dir():
            for name in files:
                if (p / name).is_dir():
                    raise UsageError(path, flag, f"{p / name} is a folder where the command "
                                     f"writes a file; {allowed}")
            if writable and not os.access(p, os.W_OK | os.X_OK):
                raise UsageError(path, flag, f"cannot write in this folder; {allowed}")
            return p
        if p.exists():
            raise UsageError(path, flag, f"is a file; {allowed}")
        above = _blocker(path, flag, p, allowed)
        if not os.access(above, os.W_OK | os.X_OK):
            raise UsageError(path, flag, f"cannot create it: {above} is not writable; {allowed}")
    except OSError as exc:
        raise UsageError(path, flag, f"unusable path ({exc.strerror}); {allowed}") from None
    return p


def _plain(path: str, flag: str, allowed: str) -> None:
    if not path.strip() or "\0" in path:
        raise UsageError(repr(path), flag, f"not a usable path; {allowed}")


def _blocker(path: str, flag: str, missing: Path, allowed: str) -> Path:
    """The nearest existing folder above ``missing``; an error if a file stands in the way."""
    for above in (missing, *missing.parents):
        if above.exists():
            if not above.is_dir():
                raise UsageError(path, flag, f"{above} is a file, not a folder; {allowed}")
            return above
    return Path(".")
