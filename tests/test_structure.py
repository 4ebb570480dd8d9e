"""The package reads as the pipeline: each stage imports only the stages before it, and no
module grows into several jobs."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "rgmcad"


def test_import_contracts_hold():
    # the contracts are in pyproject.toml ([tool.importlinter]); grimp reads every import,
    # those inside functions included
    lint = Path(sys.executable).parent / "lint-imports"
    done = subprocess.run([str(lint), "--no-cache"], capture_output=True, text=True,
                          cwd=PACKAGE.parent, timeout=120)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    assert "0 broken" in done.stdout


def test_modules_stay_small():
    sizes = {p.relative_to(PACKAGE.parent): len(p.read_text().splitlines())
             for p in PACKAGE.rglob("*.py")}
    assert not {p: n for p, n in sizes.items() if n > 450}
    commands = {p: n for p, n in sizes.items() if p.parts[1] == "cli" and p.name != "common.py"}
    assert not {p: n for p, n in commands.items() if n > 130}


@pytest.mark.slow
def test_the_wheel_alone_works_from_another_directory():
    # builds the wheel, installs it alone in a fresh environment and uses it elsewhere
    done = subprocess.run([sys.executable, str(PACKAGE.parent / "tools" / "check_wheel.py")],
                          capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stdout + done.stderr[-3000:]
