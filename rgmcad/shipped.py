"""Where the shipped part families and scenarios are: inside an installed package (a wheel
carries them as ``rgmcad/_shipped/``), else beside the package in a source checkout."""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def shipped_dir(name: str) -> Path:
    """The folder of shipped ``"parts"`` or ``"scenarios"``."""
    packaged = _PACKAGE / "_shipped" / name
    return packaged if packaged.is_dir() else _PACKAGE.parent / name


def shipped_scenarios() -> dict[str, Path]:
    """Shipped scenario files by name (the file name without ``.toml``)."""
    return {p.stem: p for p in sorted(shipped_dir("scenarios").glob("*.toml"))}


def scenario_path(name_or_path: str | Path) -> Path:
    """A scenario argument as a file: an existing path, else a shipped scenario's name (with
    or without ``.toml``), else the path as given (its loader then says it is missing)."""
    path = Path(name_or_path)
    if path.exists():
        return path
    return shipped_scenarios().get(path.name.removesuffix(".toml"), path) \
        if path.parent == Path(".") else path
