"""The report's probability slice as a user reads it: layouts whose parts overlap are greyed
(the model never saw one, its colour there would mean nothing), and a layout pushed against
them says so in the legend."""

from __future__ import annotations

import numpy as np
from PIL import Image

from rgmcad.runs.report import plot_slice
from rgmcad.scene.loader import load_scenario


class _Flat:
    """A model that predicts 0.8 everywhere."""

    def success_proba(self, P):
        return np.full(len(np.atleast_2d(P)), 0.8)


def _grey_pixels(path) -> int:
    rgb = np.asarray(Image.open(path).convert("RGB"), int)
    spread = rgb.max(axis=2) - rgb.min(axis=2)
    return int(((spread < 6) & (rgb[..., 0] > 60) & (rgb[..., 0] < 200)).sum())


def test_overlapping_layouts_are_greyed_and_the_layout_against_them_is_named(tmp_path):
    scenario = load_scenario("scenarios/simple.toml")
    influence = np.array([1.0, 0.5, 0.0])  # the slice's axes: parameters 0 and 1

    def validity(P):  # the parts meet left of 0.3 on the first axis
        return P[:, 0] >= 0.3

    x = np.array([0.31, 0.5, 0.5])
    plain, greyed = tmp_path / "plain.png", tmp_path / "greyed.png"
    assert plot_slice(scenario, _Flat(), x, influence, plain) is False
    assert plot_slice(scenario, _Flat(), x, influence, greyed, validity) is True
    assert _grey_pixels(greyed) > _grey_pixels(plain) + 5000  # a 30 % band of the plot
    away = np.array([0.8, 0.5, 0.5])
    assert plot_slice(scenario, _Flat(), away, influence, tmp_path / "away.png", validity) \
        is False
