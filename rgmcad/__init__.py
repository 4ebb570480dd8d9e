"""rgmcad: design chain-reaction contraptions that work when built by hand."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("rgmcad")  # one source: pyproject.toml's version
except PackageNotFoundError:  # a source tree that was never installed
    __version__ = "0+unknown"
