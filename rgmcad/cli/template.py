"""``rgmcad template``: a printable 1:1 tiled assembly template of a layout."""

from rgmcad.cli.printing import cmd_template as run
from rgmcad.cli.printing import configure_template as configure

__all__ = ["configure", "run"]
