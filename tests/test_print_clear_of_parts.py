"""Seam letters and world-tick labels keep off the parts they would hide: a maker reads the
outline under them."""

import numpy as np
from shapely.geometry import box

from rgmcad.printing.plane import PlaneFrame
from rgmcad.printing.seams import MARK_HALF_MM, seams_of
from rgmcad.printing.sheetpage import _world_ticks
from rgmcad.printing.tiling import tile_sheets


def _sheets():
    return tile_sheets((0.0, 0.0, 500.0, 330.0), "a4", "landscape", (2, 2), 12.0, 2)


def test_a_seam_mark_on_a_part_slides_off_it_on_both_sheets():
    sheets = _sheets()
    plain = seams_of(sheets)
    seam = plain[0]
    t, pair = seam.marks[0]
    u, v = seam.points(t)
    part = box(u - 15.0, v - 6.0, u + 15.0, v + 6.0)  # a part right on the mark
    moved = seams_of(sheets, part)
    assert moved[0].marks[1:] == seam.marks[1:]  # the others were clear
    t2, pair2 = moved[0].marks[0]
    assert pair2 == pair and abs(t2 - t) >= 6.0  # slid, same letters on both sheets
    reach = 2 * MARK_HALF_MM + 4.0
    a, b = moved[0].points(t2 - 4.0, -reach)
    c, d = moved[0].points(t2 + 4.0, reach)
    assert not box(min(a, c), min(b, d), max(a, c), max(b, d)).intersects(part)
    lo, hi = seam.span
    assert lo <= t2 <= hi


class _Recorder:
    def __init__(self):
        self.texts = []

    def polyline(self, *a, **k):
        pass

    def text(self, x, y, text, size, **k):
        self.texts.append((x, y, text))


def test_a_tick_label_on_a_part_is_left_out_and_the_others_drawn():
    sheet = _sheets()[0]
    frame = PlaneFrame("floor", "", np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0]),
                       np.array([0, 0, 1.0]))
    everything = _Recorder()
    _world_ticks(everything, sheet, frame)
    x, y, first = everything.texts[0]
    u, v = sheet.to_drawing(x, y)
    part = box(u - 2.0, v - 1.0, u + 10.0, v + 3.0)
    kept = _Recorder()
    _world_ticks(kept, sheet, frame, part)
    assert first not in [t for _, _, t in kept.texts]
    assert len(kept.texts) == len(everything.texts) - 1
