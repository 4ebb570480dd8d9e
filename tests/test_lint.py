"""Lint runs with the tests: ruff over the whole project."""

import shutil
import subprocess

import pytest


def test_ruff_is_clean():
    ruff = shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff not installed")
    result = subprocess.run([ruff, "check", "rgmcad", "parts", "tests", "tools"],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stdout
