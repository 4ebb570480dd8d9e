"""verify-print on phone photos: a fast subset of tools/photo_suite.py (3 MP photos of a
rendered sheet, ray-cast: tilted camera, tight framing, a finger over a mark, a curl)."""

from __future__ import annotations

import contextlib
import importlib.util
import io
import json
import sys
from pathlib import Path

import pytest

from rgmcad.cli import main
from rgmcad.printing.check import Verdict, verify_print

_spec = importlib.util.spec_from_file_location(
    "photo_suite", Path(__file__).resolve().parents[1] / "tools" / "photo_suite.py")
photo_suite = importlib.util.module_from_spec(_spec)
sys.modules["photo_suite"] = photo_suite  # its dataclass looks its module up there
_spec.loader.exec_module(photo_suite)
Shot = photo_suite.Shot


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    return photo_suite.make_pages(tmp_path_factory.mktemp("pages"))


def _photo(pages, tmp_path, label, shot):
    return photo_suite.photograph(pages[label][0], shot, tmp_path / "photo.jpg")


@pytest.mark.parametrize("label, shot", [
    # a few millimetres of table around the sheet, a steep angle, printed at 97 %
    ("B1", Shot(tilt_deg=33, mp=3, scale=0.97, margin_mm=4, azimuth_deg=60, seed=11)),
    # a finger over one mark, tightly framed, printed at 101.5 %
    ("B1", Shot(tilt_deg=18, mp=3, scale=1.015, finger=2, margin_mm=6, azimuth_deg=200,
                roll_deg=12, seed=12)),
    # the first page of a letter template, plenty of table
    ("map", Shot(tilt_deg=25, mp=3, scale=1.0, margin_mm=30, azimuth_deg=300, seed=13)),
])
def test_flat_sheet_photos_name_the_sheet_and_read_the_scale(pages, tmp_path, label, shot):
    check = verify_print(_photo(pages, tmp_path, label, shot))
    assert check.sheet == label
    assert check.verdict in (Verdict.OK, Verdict.REPRINT), check.message
    assert abs(check.scale - shot.scale) * 100 < 0.3, check


@pytest.mark.parametrize("curl", [("corner", 2, 40.0, 60.0), ("edge", "left", 30.0, 120.0)])
def test_a_curled_sheet_is_asked_to_be_flattened_not_given_a_wrong_scale(pages, tmp_path, curl):
    shot = Shot(tilt_deg=28, mp=3, scale=1.0, curl=curl, margin_mm=25, azimuth_deg=135, seed=14)
    check = verify_print(_photo(pages, tmp_path, "B1", shot))
    assert check.sheet == "B1"
    assert check.verdict is Verdict.NOT_FLAT and check.scale is None, check
    assert "flatten the sheet and retake" in check.message


def test_no_table_in_view_still_names_the_sheet(pages, tmp_path):
    # the photo is filled by the sheet: no edge to measure, the marks still say which sheet
    shot = Shot(tilt_deg=15, mp=3, scale=1.0, margin_mm=-6, azimuth_deg=10, seed=15)
    path = _photo(pages, tmp_path, "B1", shot)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        status = main(["verify-print", str(path), "--json"])
    got = json.loads(out.getvalue())
    assert status == 1
    assert got["sheet"] == "B1" and got["verdict"] == "no-scale" and got["scale"] is None
    assert "edges" in got["message"]
