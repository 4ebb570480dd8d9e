"""``rgmcad verify-print``: the scale a template sheet was printed at, from a scan or photo."""

from rgmcad.cli.printing import cmd_verify_print as run
from rgmcad.cli.printing import configure_verify_print as configure

__all__ = ["configure", "run"]
