"""MkDocs hook: adds the reference pages generated from the code (rgmcad.reference) to the
build, without writing them into docs/. They are made in a fresh Python process each build, so
`mkdocs serve` (which watches rgmcad/ and parts/) shows the code as it is now."""

import json
import os
import subprocess
import sys

from mkdocs.exceptions import PluginError
from mkdocs.structure.files import File


def on_files(files, config):
    # no .pyc written under rgmcad/: serve watches it, and would build once more
    done = subprocess.run([sys.executable, "-m", "rgmcad.reference"], capture_output=True,
                          text=True, check=False,
                          env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"})
    if done.returncode != 0:
        raise PluginError(f"rgmcad.reference failed:\n{done.stderr[-3000:]}")
    for path, text in json.loads(done.stdout).items():
        files.append(File.generated(config, path, content=text))
    return files


def on_page_markdown(markdown, page, config, files):
    from pathlib import Path

    from rgmcad.reference.results import fill

    return fill(markdown, Path(config["config_file_path"]).parent)
