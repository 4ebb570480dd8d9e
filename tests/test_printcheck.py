"""verify_print on simulated scans and photos of rendered template sheets."""

from __future__ import annotations

import cv2
import numpy as np
import pypdfium2 as pdfium
import pytest
import trimesh
from PIL import Image

from rgmcad.errors import PrintCheckError
from rgmcad.printing.check import verify_print
from rgmcad.printing.inputs import BasePlane, PlacedPart
from rgmcad.printing.template import make_template

DPI = 300


def _box(name, order, centre, size):
    m = trimesh.creation.box(size)
    pose = np.eye(4)
    pose[:3, 3] = centre
    m.apply_transform(pose)
    return PlacedPart(name, order, np.asarray(m.vertices), np.asarray(m.faces), pose)


def _render_page(pdf_path, index):
    doc = pdfium.PdfDocument(str(pdf_path))
    img = np.asarray(doc[index].render(scale=DPI / 72).to_pil().convert("L"))
    doc.close()
    return img


@pytest.fixture(scope="module")
def sheets(tmp_path_factory):
    """Rendered pages: sheet B1 of an a4 landscape template, and a letter template's map."""
    out = tmp_path_factory.mktemp("printcheck")
    floor = BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))
    parts = [_box("a", 1, (0.0, 0.0, 0.01), (0.1, 0.05, 0.02)),
             _box("b", 2, (0.3, 0.05, 0.01), (0.1, 0.05, 0.02))]
    a4 = make_template(parts, [floor], out / "a4", paper="a4", orientation="landscape")
    assert a4.grid[0] >= 2
    b1 = next(s for s in a4.sheets if s.label == "B1")
    letter = make_template(parts[:1], [floor], out / "letter", paper="letter")
    return {"B1": _render_page(a4.pdf, b1.page - 1),
            "map": _render_page(letter.pdf, letter.map_sheet.page - 1)}


def shrink(page, scale):
    """The page printed at ``scale``: content resampled about the centre, same paper."""
    h, w = page.shape
    small = cv2.resize(page, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    out = np.full_like(page, 255)
    sh, sw = small.shape
    y0, x0 = (h - sh) // 2, (w - sw) // 2
    ys, xs = slice(max(y0, 0), max(y0, 0) + min(sh, h)), slice(max(x0, 0), max(x0, 0) + min(sw, w))
    out[ys, xs] = small[max(-y0, 0):max(-y0, 0) + min(sh, h), max(-x0, 0):max(-x0, 0) + min(sw, w)]
    return out


def photograph(sheet, seed=0):
    """A photo of a sheet lying on a darker table: perspective, blur, noise, no dpi."""
    rng = np.random.default_rng(seed)
    h, w = sheet.shape
    pad = 400
    table = np.full((h + 2 * pad, w + 2 * pad), 70.0)
    table += np.linspace(-15, 15, table.shape[1])[None, :]  # uneven light
    table[pad:pad + h, pad:pad + w] = sheet
    th, tw = table.shape
    src = np.float32([[0, 0], [tw, 0], [tw, th], [0, th]])
    f = 0.55  # the photo has fewer pixels than the scan
    dst = np.float32([[120, 60], [tw - 90, 170], [tw - 10, th - 30], [30, th - 200]]) * f
    m = cv2.getPerspectiveTransform(src, dst)
    photo = cv2.warpPerspective(table, m, (int(tw * f) + 20, int(th * f) + 20),
                                flags=cv2.INTER_AREA, borderValue=60.0)
    photo = cv2.GaussianBlur(photo, (0, 0), 1.3)
    photo += rng.normal(0.0, 4.0, photo.shape)
    return np.clip(photo, 0, 255).astype(np.uint8)


def _save(tmp_path, name, img, dpi=None, **kw):
    path = tmp_path / name
    extra = {"dpi": (dpi, dpi)} if dpi else {}
    Image.fromarray(img).save(path, **extra, **kw)
    return path


@pytest.mark.parametrize("scale", [0.97, 1.0])
def test_scan_with_dpi(sheets, tmp_path, scale):
    path = _save(tmp_path, "scan.png", shrink(sheets["B1"], scale), dpi=DPI)
    check = verify_print(path)
    assert check.method == "dpi"
    assert check.sheet == "B1" and check.paper == "a4"
    assert check.tag_ids == (4 * 2, 4 * 2 + 1, 4 * 2 + 2, 4 * 2 + 3)  # slot 1 + col 1 = 2
    assert abs(check.scale_error_percent - 100 * (scale - 1)) < 0.3, check
    if scale < 1:
        assert "reprint" in check.message and "97.0 %" in check.message
    else:
        assert check.message.startswith("scale OK")


@pytest.mark.parametrize("scale", [0.97, 1.0])
def test_photo_without_dpi(sheets, tmp_path, scale):
    path = _save(tmp_path, "photo.png", photograph(shrink(sheets["B1"], scale)))
    with Image.open(path) as im:
        assert "dpi" not in im.info
    check = verify_print(path)
    assert check.method == "sheet-edges"
    assert check.sheet == "B1" and check.paper == "a4"
    assert abs(check.scale_error_percent - 100 * (scale - 1)) < 0.3, check
    assert all(abs(s - scale) < 0.004 for s in check.scale_xy)


def test_phone_photo_with_bogus_72_dpi(sheets, tmp_path):
    path = _save(tmp_path, "phone.jpg", photograph(shrink(sheets["B1"], 0.97), seed=3),
                 dpi=72, quality=92)
    check = verify_print(path)
    assert check.method == "sheet-edges"
    assert abs(check.scale_error_percent + 3.0) < 0.3, check


def test_first_page_of_a_letter_template(sheets, tmp_path):
    path = _save(tmp_path, "map.png", shrink(sheets["map"], 0.98), dpi=DPI)
    check = verify_print(path)
    assert check.sheet == "map" and check.paper == "letter" and check.tag_ids == (0, 1, 2, 3)
    assert abs(check.scale_error_percent + 2.0) < 0.3, check
    path = _save(tmp_path, "map-photo.png", photograph(sheets["map"], seed=5))
    check = verify_print(path)
    assert check.paper == "letter" and check.method == "sheet-edges"
    assert abs(check.scale_error_percent) < 0.3, check


def test_unreadable_and_tagless_images(tmp_path):
    bad = tmp_path / "broken.png"
    bad.write_bytes(b"this is not an image")
    for path in (bad, tmp_path / "missing.png"):
        with pytest.raises(PrintCheckError) as err:
            verify_print(path)
        assert "cannot read" in str(err.value) and "\n" not in str(err.value)
    rng = np.random.default_rng(0)
    blank = _save(tmp_path, "blank.png", rng.integers(100, 255, (800, 600), dtype=np.uint8))
    with pytest.raises(PrintCheckError) as err:
        verify_print(blank)
    assert "no template marks" in str(err.value) and "\n" not in str(err.value)
    assert str(blank) in str(err.value)
