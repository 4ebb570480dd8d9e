"""Helpers for tests: tiny scenarios written as dicts, simulated with the real engine."""

from __future__ import annotations

import contextlib
import io
import json
import signal
import subprocess

import numpy as np

from rgmcad.cli import main
from rgmcad.learning import LearningSettings
from rgmcad.parts.store import PartStore
from rgmcad.scene.bodies import load_parts, make_scene
from rgmcad.scene.design_space import values_from_mapping
from rgmcad.scene.loader import parse_scenario
from rgmcad.sim.run import simulate

PARTS = PartStore()
"""One store for the test session: a part is read from disk once."""


def tiny(objects: dict, events: dict, *, runs=None, joints=None, duration=2.0, **sim):
    """A scenario from plain dicts (the TOML structure)."""
    data = {"name": "tiny", "objects": objects, "events": events,
            "simulation": {"duration": duration, **sim}}
    if runs:
        data["runs"] = runs
    if joints:
        data["joints"] = joints
    return parse_scenario(data, where="<test>")


def run(scenario, layout: str = "initial", **kwargs):
    parts = load_parts(scenario, PARTS)
    values = values_from_mapping(scenario, scenario.layouts[layout])
    return simulate(scenario, values, parts, **kwargs)


def scene_of(scenario, values=None):
    parts = load_parts(scenario, PARTS)
    if values is None:
        values = values_from_mapping(scenario, scenario.layouts["initial"])
    return make_scene(scenario, np.asarray(values, float), parts)


# A budget small enough for the fast suite (a few seconds per run on one core).
TINY = LearningSettings(
    n_initial=40, n_successes=8, exploration_max_iter=8, active_batch=5, active_max_iter=1,
    svm_C_grid=(1.0, 10.0, 100.0), svm_gamma_grid=(1.0, 10.0), svm_class_weights=(None,),
    mi_null_permutations=2, placement_samples=4, optimizer_max_eval=40,
    centering_simulations=0, verify_samples=64,  # a race of two stages, 32 and 64 errors
)


def cli_output(argv) -> tuple[int, str, str]:
    """``rgmcad ARGV`` in this process: its exit status, stdout and stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as e:  # argparse's own refusals
            code = e.code
    return code, out.getvalue(), err.getvalue()


def run_cli(argv) -> tuple[int, dict | None]:
    """``rgmcad ARGV`` in this process: its exit status and its JSON output (None if none)."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = main(argv)
    text = out.getvalue().strip()
    return code, (json.loads(text) if text else None)


def popen_as_terminal(command, **kwargs) -> subprocess.Popen:
    """``subprocess.Popen(command, **kwargs)`` in a session of its own, with SIGINT's default
    action, as a terminal's foreground job has it: Ctrl-C is then ``os.killpg(p.pid, SIGINT)``.
    A test run started in the background by a script inherits SIGINT ignored, and so would
    the command (Python sets no KeyboardInterrupt handler then), unless the disposition here
    is a handler, which exec resets to the default."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        return subprocess.Popen(command, start_new_session=True, **kwargs)
    finally:
        signal.signal(signal.SIGINT, signal.SIG_DFL if before is None else before)
