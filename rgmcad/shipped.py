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
