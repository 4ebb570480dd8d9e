"""Synthetic phone photos of printed template sheets, and how `verify-print` reads them.

Each photo is ray-cast: a pinhole camera 10-35 degrees off vertical looks at a sheet lying on
a darker, textured table. The sheet is a rendered template page printed at a known scale; it
may be flat, have a curled edge or corner (a true bend: the paper keeps its length and lifts
off the table along a circular arc), have a finger over one of its marks, and the photo may
be framed tightly, with only a few millimetres of table around the paper. Then optics blur,
sensor noise and JPEG compression. The truth (sheet, scale, flat or not) goes with each.

    uv run python tools/photo_suite.py --out /tmp/photos [--count 48] [--seed 1]

prints one line per photo and the suite's figures: sheets named, flat sheets whose scale is
within 0.3 %, curled sheets warned. ``photograph`` and ``make_pages`` are also used by
tests/test_print_photos.py on a small subset.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

DPI = 300
K_PAGE = DPI / 25.4  # px per mm of the rendered page


@dataclass(frozen=True)
class Shot:
    """How one photo is taken.

    ``tilt_deg``: camera axis from vertical; ``mp``: megapixels (3 or 12); ``scale``: print
    scale; ``curl``: None, ``("edge", side, length_mm, radius_mm)`` or ``("corner", corner,
    length_mm, radius_mm)``; ``finger``: index 0-3 of the mark covered, or None;
    ``margin_mm``: table visible around the paper at the tightest side; ``distortion``:
    radial lens distortion k1 (relative to the half diagonal; 0.01 moves the corners 1 %).
    """

    tilt_deg: float
    mp: int
    scale: float = 1.0
    curl: tuple | None = None
    finger: int | None = None
    margin_mm: float = 40.0
    azimuth_deg: float = 0.0
    roll_deg: float = 0.0
    seed: int = 0
    distortion: float = 0.0


def make_pages(out_dir: Path):
    """Render two template sheets at 300 dpi: ``{label: (grey page, paper)}``.

    An a4 landscape sheet B1 and the first page of a letter template, from a few boxes.
    """
    import pypdfium2 as pdfium
    import trimesh

    from rgmcad.printing.inputs import BasePlane, PlacedPart
    from rgmcad.printing.template import make_template

    def box(name, order, centre, size):
        m = trimesh.creation.box(size)
        pose = np.eye(4)
        pose[:3, 3] = centre
        m.apply_transform(pose)
        return PlacedPart(name, order, np.asarray(m.vertices), np.asarray(m.faces), pose)

    floor = BasePlane("floor", np.zeros(3), np.array([0.0, 0.0, 1.0]))
    parts = [box("a", 1, (0.0, 0.0, 0.01), (0.1, 0.05, 0.02)),
             box("b", 2, (0.3, 0.05, 0.01), (0.1, 0.05, 0.02))]
    a4 = make_template(parts, [floor], out_dir / "a4", paper="a4", orientation="landscape")
    letter = make_template(parts[:1], [floor], out_dir / "letter", paper="letter")
    pages = {}
    for result, sheet, paper in ((a4, a4.sheets[1], "a4"), (letter, letter.map_sheet, "letter")):
        doc = pdfium.PdfDocument(str(result.pdf))
        pages[sheet.label] = (np.asarray(doc[sheet.page - 1].render(scale=DPI / 72)
                                         .to_pil().convert("L")), paper)
        doc.close()
    return pages


def _printed(page: np.ndarray, scale: float) -> np.ndarray:
    h, w = page.shape
    m = np.float32([[scale, 0, (1 - scale) * w / 2], [0, scale, (1 - scale) * h / 2]])
    return cv2.warpAffine(page, m, (w, h), flags=cv2.INTER_AREA, borderValue=255)


def _camera(shot: Shot, size_mm, rng):
    """Camera centre, rotation (rows: image x, image y, forward) and image size."""
    w, h = size_mm
    target = np.array([w / 2, h / 2, 0.0]) + np.append(rng.uniform(-10, 10, 2), 0.0)
    t, a = math.radians(shot.tilt_deg), math.radians(shot.azimuth_deg)
    view = np.array([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)])
    centre = target + 600.0 * view
    fwd = -view
    r = math.radians(shot.roll_deg)
    hint = np.array([math.sin(r), -math.cos(r), 0.0])  # image up, roughly the paper's top
    down = -(hint - (hint @ fwd) * fwd)
    down /= np.linalg.norm(down)
    right = np.cross(fwd, down)  # the table frame (x right, y down, z up) is left-handed
    return centre, np.stack([right, down, fwd])


def _fit_intrinsics(centre, rot, size_mm, margin, mp):
    """Focal length and image size so the paper plus ``margin`` mm just fits the frame."""
    w, h = size_mm
    pts = np.array([[-margin, -margin, 0], [w + margin, -margin, 0], [w + margin, h + margin, 0],
                    [-margin, h + margin, 0]], float)
    cam = (pts - centre) @ rot.T
    uv = cam[:, :2] / cam[:, 2:]
    span = uv.max(0) - uv.min(0)
    long_px = math.sqrt(mp * 1e6 * 4 / 3)
    dims = (int(long_px), int(long_px * 3 / 4))
    if span[1] > span[0]:
        dims = dims[::-1]
    f = min(dims[0] / span[0], dims[1] / span[1])
    c = np.array(dims) / 2 - f * (uv.max(0) + uv.min(0)) / 2
    return f, c, dims


def _curl_geometry(curl, size_mm):
    """Bend line point ``p0``, along ``d``, into-curl ``n`` (table plane, mm), radius."""
    w, h = size_mm
    kind, where, length, radius = curl
    if kind == "edge":
        p0, d, n = {"left": ((length, 0), (0, 1), (-1, 0)),
                    "right": ((w - length, 0), (0, 1), (1, 0)),
                    "top": ((0, length), (1, 0), (0, -1)),
                    "bottom": ((0, h - length), (1, 0), (0, 1))}[where]
    else:
        corner = np.array([(0, 0), (w, 0), (w, h), (0, h)][where], float)
        inward = np.array([(1, 1), (-1, 1), (-1, -1), (1, -1)][where], float) / math.sqrt(2)
        p0, n = corner + length * inward, -inward
        d = (n[1], -n[0])
    return np.array(p0, float), np.array(d, float), np.array(n, float), float(radius)


def _trace(rays, centre, size_mm, curl):
    """Paper coordinates (mm) hit by rays (n, 3) from ``centre``, or NaN; also the table
    point each ray meets and the surface's tilt factor for shading."""
    w, h = size_mm
    n = len(rays)
    q = np.full((n, 2), np.nan)
    t_plane = -centre[2] / rays[:, 2]
    table = centre[:2] + t_plane[:, None] * rays[:, :2]
    shade = np.ones(n)
    flat = table.copy()
    lifted = np.zeros(n, bool)
    if curl is not None:
        p0, d, nn, radius = _curl_geometry(curl, size_mm)
        s_flat = (flat - p0) @ nn
        lifted = s_flat > 0  # the paper there has left the table
        a0, da = (centre[:2] - p0) @ nn, rays[:, :2] @ nn
        b0, db = centre[2] - radius, rays[:, 2]
        qa, qb, qc = da**2 + db**2, 2 * (a0 * da + b0 * db), a0**2 + b0**2 - radius**2
        disc = qb**2 - 4 * qa * qc
        ok = disc >= 0
        best_t = np.full(n, np.inf)
        for sign in (-1.0, 1.0):
            tt = np.where(ok, (-qb + sign * np.sqrt(np.maximum(disc, 0))) / (2 * qa), np.nan)
            aa = a0 + tt * da
            bb = centre[2] + tt * rays[:, 2]
            phi = np.arctan2(aa, radius - bb)
            pt = centre[:2] + tt[:, None] * rays[:, :2]
            along = (pt - p0) @ d
            cand = p0 + along[:, None] * d + (radius * phi)[:, None] * nn
            inside = ((phi > 0) & (cand[:, 0] >= 0) & (cand[:, 0] <= w) & (cand[:, 1] >= 0)
                      & (cand[:, 1] <= h) & (tt > 0))
            take = inside & (tt < best_t)
            best_t[take] = tt[take]
            q[take] = cand[take]
            shade[take] = 0.88 + 0.12 * np.cos(phi[take])
    on_flat = (~lifted & (flat[:, 0] >= 0) & (flat[:, 0] <= w) & (flat[:, 1] >= 0)
               & (flat[:, 1] <= h) & np.isnan(q[:, 0]))
    q[on_flat] = flat[on_flat]
    return q, table, shade


def _table(points, rng_phase):
    x, y = points[:, 0], points[:, 1]
    grain = 9.0 * np.sin(x / 23.0 + 3.0 * np.sin(y / 71.0 + rng_phase)) + 5.0 * np.sin(y / 9.0)
    return 85.0 + grain + 0.04 * (x - y)


def photograph(page: np.ndarray, shot: Shot, path: Path) -> Path:
    """Write a JPEG photo of ``page`` (grey, 300 dpi) taken as ``shot`` says."""
    rng = np.random.default_rng(shot.seed)
    paper = _printed(page, shot.scale)
    size_mm = (page.shape[1] / K_PAGE, page.shape[0] / K_PAGE)
    centre, rot = _camera(shot, size_mm, rng)
    f, c, dims = _fit_intrinsics(centre, rot, size_mm, shot.margin_mm, shot.mp)
    k_photo = f / 600.0  # px per mm at the paper, roughly
    sigma = max(0.0, 0.5 * K_PAGE / k_photo - 0.3)
    paper = cv2.GaussianBlur(paper, (0, 0), sigma) if sigma > 0.3 else paper
    # where each pixel's ray meets the table plane: exact on a coarse grid, then linear
    step = 8
    # (cv2.resize puts coarse sample j at fine pixel (j + 0.5) step - 0.5)
    gu, gv = np.meshgrid((np.arange(dims[0] // step + 2) + 0.5) * step - 0.5,
                         (np.arange(dims[1] // step + 2) + 0.5) * step - 0.5)
    rays = np.stack([(gu.ravel() - c[0]) / f, (gv.ravel() - c[1]) / f, np.ones(gu.size)], 1) @ rot
    t_plane = -centre[2] / rays[:, 2]
    grid = centre[:2] + t_plane[:, None] * rays[:, :2]
    tx, ty = (cv2.resize(grid[:, i].reshape(gu.shape).astype(np.float32), None, fx=step, fy=step,
                         interpolation=cv2.INTER_LINEAR)[:dims[1], :dims[0]] for i in (0, 1))
    out = _table(np.stack([tx.ravel(), ty.ravel()], 1), rng.uniform(0, 6)).reshape(tx.shape)
    out = out.astype(np.float32)
    w, h = size_mm
    qx, qy, shade = tx.copy(), ty.copy(), np.ones_like(tx)
    paper_here = (tx >= 0) & (tx <= w) & (ty >= 0) & (ty <= h)
    if shot.curl is not None:  # ray-trace the pixels near the curl exactly
        p0, _, nn, _ = _curl_geometry(shot.curl, size_mm)
        near = ((tx - p0[0]) * nn[0] + (ty - p0[1]) * nn[1]) > -40.0
        vv, uu = np.nonzero(near)
        rays = np.stack([(uu - c[0]) / f, (vv - c[1]) / f, np.ones(uu.size)], 1) @ rot
        q, _, sh = _trace(rays, centre, size_mm, shot.curl)
        hit = ~np.isnan(q[:, 0])
        paper_here[vv, uu] = hit
        qx[vv[hit], uu[hit]], qy[vv[hit], uu[hit]] = q[hit, 0], q[hit, 1]
        shade[vv, uu] = sh
    got = cv2.remap(paper, qx * K_PAGE - 0.5, qy * K_PAGE - 0.5, cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE).astype(np.float32)
    out = np.where(paper_here, (0.93 * got + 8.0) * shade, out)
    if shot.finger is not None:  # a finger from outside the sheet, over one mark
        from rgmcad.printing.sheets import MARGIN_MM, TAG_SIDE_MM
        half = MARGIN_MM + TAG_SIDE_MM / 2
        tip = np.array([(half, half), (w - half, half), (w - half, h - half),
                        (half, h - half)][shot.finger], float)
        away = (tip - np.array(size_mm) / 2) / np.linalg.norm(tip - np.array(size_mm) / 2)
        along = (qx - tip[0]) * away[0] + (qy - tip[1]) * away[1]
        across = -(qx - tip[0]) * away[1] + (qy - tip[1]) * away[0]
        inside = ((along > -9.0) & (np.abs(across) < 9.0)) | ((along + 9.0) ** 2 + across**2 < 81)
        out[inside] = 150.0 + 10.0 * np.cos(across[inside] / 9.0)
    yy, xx = np.mgrid[0:dims[1], 0:dims[0]]
    vignette = 1.0 - 0.18 * (((xx - dims[0] / 2) / dims[0]) ** 2 + ((yy - dims[1] / 2) / dims[1]) ** 2)
    a = rng.uniform(0, 2 * math.pi)  # light falling off across the table
    vignette *= 1.0 - 0.15 * (0.5 + 0.5 * ((xx / dims[0] - 0.5) * math.cos(a)
                                           + (yy / dims[1] - 0.5) * math.sin(a)))
    out = out * vignette.astype(np.float32)
    if shot.distortion:
        r2 = ((xx - dims[0] / 2) ** 2 + (yy - dims[1] / 2) ** 2) / ((dims[0] ** 2 + dims[1] ** 2) / 4)
        grow = (1.0 + shot.distortion * r2).astype(np.float32)
        out = cv2.remap(out, ((xx - dims[0] / 2) * grow + dims[0] / 2).astype(np.float32),
                        ((yy - dims[1] / 2) * grow + dims[1] / 2).astype(np.float32),
                        cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    out = cv2.GaussianBlur(out, (0, 0), 0.8 + 0.4 * rng.random())
    out += rng.normal(0.0, 3.0, out.shape).astype(np.float32)
    cv2.imwrite(str(path), np.clip(out, 0, 255).astype(np.uint8),
                [cv2.IMWRITE_JPEG_QUALITY, 90])
    return path


def suite(count: int, seed: int, distortion: float = 0.0) -> list[tuple[str, Shot]]:
    """``count`` shots over tilts 10-35 degrees, 3 and 12 MP, print scales 97-103 %: flat
    (with plenty of table or little), a finger over a mark, curled edges and corners."""
    rng = np.random.default_rng(seed)
    kinds = ["flat", "tight", "finger", "tight-finger", "curl-edge", "curl-corner"]
    shots = []
    for i in range(count):
        kind = kinds[i % len(kinds)]
        curl = None
        if kind == "curl-edge":
            curl = ("edge", ["left", "right", "top", "bottom"][rng.integers(4)],
                    float(rng.uniform(25, 70)), float(rng.uniform(50, 150)))
        elif kind == "curl-corner":
            curl = ("corner", int(rng.integers(4)), float(rng.uniform(25, 60)),
                    float(rng.uniform(30, 100)))
        shots.append((["B1", "map"][(i // len(kinds)) % 2], Shot(
            tilt_deg=float(rng.uniform(10, 35)), mp=[3, 12][(i // 2) % 2],
            scale=float(rng.choice([0.97, 0.985, 1.0, 1.0, 1.015, 1.03])), curl=curl,
            finger=int(rng.integers(4)) if "finger" in kind else None,
            margin_mm=float(rng.uniform(3, 10)) if "tight" in kind else float(rng.uniform(20, 50)),
            azimuth_deg=float(rng.uniform(0, 360)), roll_deg=float(rng.uniform(-20, 20)),
            seed=seed * 1000 + i, distortion=float(rng.uniform(-distortion, distortion)))))
    return shots


def main(argv=None) -> int:
    from rgmcad.printing.check import Verdict, verify_print

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=None, help="folder for the photos")
    ap.add_argument("--count", type=int, default=48)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--distortion", type=float, default=0.0, metavar="K1",
                    help="radial lens distortion drawn in [-K1, K1] (default 0: none)")
    args = ap.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix="photos-"))
    out.mkdir(parents=True, exist_ok=True)
    pages = make_pages(out)
    named = flat_ok = flat_n = curled_warned = curled_n = 0
    worst_flat = 0.0
    for i, (label, shot) in enumerate(suite(args.count, args.seed, args.distortion)):
        page, _ = pages[label]
        path = photograph(page, shot, out / f"photo{i:03d}.jpg")
        t0 = time.perf_counter()
        check = verify_print(path)
        wall = time.perf_counter() - t0
        named += check.sheet == label
        if shot.curl is None:
            flat_n += 1
            err = (abs(check.scale - shot.scale) * 100 if check.scale is not None else math.inf)
            worst_flat = max(worst_flat, err)
            flat_ok += err <= 0.3
        else:
            curled_n += 1
            curled_warned += check.verdict is Verdict.NOT_FLAT
        got = f"{check.scale * 100:.2f} %" if check.scale is not None else "-"
        print(f"{path.name} {label} tilt {shot.tilt_deg:4.1f} {shot.mp:2d} MP scale "
              f"{shot.scale * 100:5.1f} % margin {shot.margin_mm:4.1f} finger {shot.finger} "
              f"curl {shot.curl and shot.curl[:2]} k1 {shot.distortion:+.4f} -> {check.sheet} "
              f"{check.verdict.value} "
              f"{got} marks-misfit {check.residual_mm:.3f} bow {check.bow_mm:.2f} "
              f"({wall:.1f} s)")
    total = args.count
    print(f"sheet named: {named}/{total}; flat sheets within 0.3 %: {flat_ok}/{flat_n} "
          f"(worst {worst_flat:.2f} points); curled sheets warned: {curled_warned}/{curled_n}")
    return 0 if named == total and flat_ok == flat_n and curled_warned == curled_n else 1


if __name__ == "__main__":
    sys.exit(main())
