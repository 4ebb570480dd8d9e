"""``rgmcad evaluate``: a layout's local and global robustness, by simulation."""

from rgmcad.cli.optimize import cmd_evaluate as run
from rgmcad.cli.optimize import configure_evaluate as configure

__all__ = ["configure", "run"]
