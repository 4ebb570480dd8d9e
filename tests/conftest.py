"""Hermetic part cache: tests (and the commands they start, which inherit the environment)
cache built parts in the checkout's ``build/parts``, never in the user's cache folder."""

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

os.environ["RGMCAD_CACHE"] = str(ROOT / "build" / "parts")
