"""A plot that cannot be written for want of space names its file: the ``write(2)`` that
finds the disk full names none, and the command's one-line refusal said "an output file"."""

from __future__ import annotations

import errno
import os

import matplotlib
import pytest

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from rgmcad.files import cannot_write  # noqa: E402
from rgmcad.runs.robustness import save_plot  # noqa: E402


def test_a_plot_saved_on_a_full_disk_names_its_file(tmp_path, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))  # as write(2) says it: no file

    monkeypatch.setattr(FigureCanvasAgg, "print_png", full)
    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1], label="a line")
    path = tmp_path / "robustness.png"
    with pytest.raises(OSError) as caught:
        save_plot(fig, ax, path)
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(path)
    line = f"rgmcad: error: {caught.value.filename}: {cannot_write(caught.value)}"  # as the CLI
    assert str(path) in line and "free some space" in line, line
