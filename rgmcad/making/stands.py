"""A stand: a block that rests flat on a base plane and meets a raised part's face at its
pose; its mesh, its CadQuery solid, and its flat card alternative.

A stand is a straight prism over a rectangle on its base plane (the floor, or a board it is
glued to), cut on top by the plane of the part's face that looks towards the base: a tilted
part gets a tilted top. Its faces are the flat base, vertical sides and a top whose normal
points away from the base, so it prints base down with no support material whatever the
tilt. Lengths are metres unless a name says millimetres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from rgmcad.geometry import matmul, transform_points

__all__ = ["Stand", "card_net", "write_stand_files", "stand_solid", "stand_from_json",
           "read_stands", "MIN_HEIGHT"]

MIN_HEIGHT = 0.001
"""m: a stand's top is at least this far from its base at every corner."""

_FACES = np.array([[0, 2, 1], [0, 3, 2],  # base, seen from outside (below)
                   [4, 5, 6], [4, 6, 7],  # top
                   [0, 1, 5], [0, 5, 4], [1, 2, 6], [1, 6, 5],
                   [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]])


@dataclass(frozen=True, eq=False)
class Stand:
    """One stand.

    Attributes
    ----------
    label : str
        ``S1``, ``S2``, ... in placement order.
    part : str
        The static part it holds (:class:`~rgmcad.making.supports.StaticPart` name).
    base : str
        The base plane it rests on.
    frame : (4, 4) float
        World transform of the stand's frame: origin on the base plane, z the base plane's
        normal (towards the part), x along the part's length.
    corners : (4, 2) float
        The base rectangle's corners (u, v) in ``frame``, counter-clockwise seen from +z.
    top : (3,) float
        The top plane as heights ``w = a u + b v + c`` above the base, in ``frame``.
    """

    label: str
    part: str
    base: str
    frame: np.ndarray
    corners: np.ndarray
    top: np.ndarray

    def heights(self) -> np.ndarray:
        """(4,) m: the top's height above the base at each corner."""
        return self.corners @ self.top[:2] + self.top[2]

    @property
    def size(self) -> tuple[float, float]:
        """(length, width) of the base rectangle, m."""
        c = self.corners
        return float(np.linalg.norm(c[1] - c[0])), float(np.linalg.norm(c[3] - c[0]))

    @property
    def tilt_deg(self) -> float:
        """The top's angle to the base, degrees."""
        return math.degrees(math.atan(math.hypot(*self.top[:2])))

    def local_vertices(self) -> np.ndarray:
        """(8, 3) m: base corners then top corners, in ``frame``."""
        base = np.column_stack([self.corners, np.zeros(4)])
        return np.vstack([base, np.column_stack([self.corners, self.heights()])])

    def vertices(self) -> np.ndarray:
        """(8, 3) world vertices, m: base corners then top corners."""
        return transform_points(self.frame, self.local_vertices())

    def mesh(self):
        """The stand as a watertight ``trimesh.Trimesh`` in world metres (12 triangles)."""
        import trimesh

        return trimesh.Trimesh(self.vertices(), _FACES.copy(), process=False)

    def footprint(self) -> np.ndarray:
        """(4, 3) world points of the base rectangle, m."""
        return self.vertices()[:4]

    def moved(self, transform: np.ndarray) -> Stand:
        """The stand moved rigidly by the (4, 4) world ``transform``."""
        return replace(self, frame=matmul(transform, self.frame))

    def describe(self) -> str:
        """One line for a person: size, heights (mm) and tilt (degrees)."""
        length, width = self.size
        h = self.heights() * 1000
        tilt = f", top tilted {self.tilt_deg:.1f}°" if self.tilt_deg >= 0.05 else ""
        return (f"{self.label} under {self.part}: {length * 1000:.1f} x {width * 1000:.1f} mm "
                f"on the {self.base}, {h.min():.1f} to {h.max():.1f} mm high{tilt}")

    def to_json(self) -> dict:
        """JSON-ready: a summary (millimetres and degrees, world footprint in metres) and the
        geometry :func:`stand_from_json` reads back (``frame``, ``corners``, ``top``, SI)."""
        length, width = self.size
        h = self.heights() * 1000
        return {"label": self.label, "part": self.part, "base": self.base,
                "length_mm": round(length * 1000, 1), "width_mm": round(width * 1000, 1),
                "height_mm": [round(float(h.min()), 1), round(float(h.max()), 1)],
                "tilt_deg": round(self.tilt_deg, 1),
                "footprint_world": self.footprint().round(6).tolist(),
                "frame": self.frame.tolist(), "corners": self.corners.tolist(),
                "top": self.top.tolist()}


def read_stands(path: Path) -> list[Stand]:
    """The stands of a ``supports.json`` (``rgmcad supports``); ValueError saying what is
    wrong with the file."""
    import json

    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"cannot read the stands ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("stands"), list):
        raise ValueError("expected the supports.json of `rgmcad supports` (a `stands` list)")
    return [stand_from_json(item) for item in data["stands"]]


def stand_from_json(data) -> Stand:
    """A :class:`Stand` from :meth:`Stand.to_json`; ValueError naming what is wrong."""
    try:
        stand = Stand(str(data["label"]), str(data["part"]), str(data["base"]),
                      np.array(data["frame"], float), np.array(data["corners"], float),
                      np.array(data["top"], float))
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"a stand needs label, part, base, frame, corners and top ({exc})") \
            from None
    shapes = (stand.frame.shape, stand.corners.shape, stand.top.shape)
    if shapes != ((4, 4), (4, 2), (3,)) or not all(
            np.all(np.isfinite(a)) for a in (stand.frame, stand.corners, stand.top)):
        raise ValueError(f"stand {stand.label}: frame (4, 4), corners (4, 2) and top (3,) "
                         "finite numbers expected")
    return stand


def stand_solid(stand: Stand, mm: float = 1000.0):
    """The stand as a CadQuery solid in world millimetres (``mm`` = 1: metres): the base
    rectangle extruded past the top, cut by the top plane (CadQuery is imported here)."""
    import cadquery as cq

    local = stand.local_vertices() * mm
    high = float(local[:, 2].max()) + 0.01 * mm
    block = cq.Workplane("XY").polyline([tuple(p) for p in local[:4, :2]]).close().extrude(high)
    a, b, _ = stand.top
    normal = np.array([-a, -b, 1.0]) / math.sqrt(a * a + b * b + 1.0)  # out of the top
    centre = local[4:].mean(axis=0)
    x_dir = np.cross([0.0, 1.0, 0.0], normal)
    plane = cq.Plane(origin=tuple(centre), xDir=tuple(x_dir / np.linalg.norm(x_dir)),
                     normal=tuple(normal))
    span = 4.0 * (float(np.ptp(local[:, :2], axis=0).max()) + high)
    below = cq.Workplane(plane).rect(span, span).extrude(-span)
    solid = block.intersect(below).val()
    m = stand.frame.copy()
    m[:3, 3] *= mm
    return solid.transformGeometry(cq.Matrix([list(row) for row in m[:3]]))


def card_net(stand: Stand) -> list[tuple[str, np.ndarray]]:
    """The stand as a card box to cut and fold: ``[(kind, (n, 2) mm polyline)]`` with kind
    ``"cut"`` or ``"fold"``. The four sides are one strip (each side's height at its two
    corners, so the top comes out at the part's tilt), a glue tab at its end, and the top and
    the base as separate pieces below it, each with its true shape."""
    mm = 1000.0
    c, h = stand.corners * mm, stand.heights() * mm
    edges = [float(np.linalg.norm(c[(i + 1) % 4] - c[i])) for i in range(4)]
    xs = np.concatenate([[0.0], np.cumsum(edges)])
    tops = np.append(h, h[0])
    back = [(x, t) for x, t in zip(xs[::-1], tops[::-1], strict=True)]
    strip = [(xs[0], 0.0), *[(x, 0.0) for x in xs[1:]], (xs[-1] + 8.0, 3.0),
             (xs[-1] + 8.0, tops[-1] - 3.0), *back]
    out = [("cut", np.array(strip + [strip[0]]))]
    out += [("fold", np.array([[x, 0.0], [x, t]])) for x, t in zip(xs[1:], tops[1:], strict=True)]
    below = -10.0
    top3 = stand.local_vertices()[4:] * mm
    u = top3[1] - top3[0]
    u /= np.linalg.norm(u)
    n = np.cross(top3[1] - top3[0], top3[3] - top3[0])
    v = np.cross(n / np.linalg.norm(n), u)
    top2 = np.column_stack([(top3 - top3[0]) @ u, (top3 - top3[0]) @ v])
    top2 += [0.0, below - top2[:, 1].max()]
    base2 = c - c[0] + [top2[:, 0].max() + 10.0, below - (c[:, 1] - c[0, 1]).max()]
    out += [("cut", np.vstack([top2, top2[:1]])), ("cut", np.vstack([base2, base2[:1]]))]
    return out


def _net_svg(stand: Stand) -> str:
    net = card_net(stand)
    pts = np.concatenate([p for _, p in net])
    lo, hi = pts.min(0) - 5.0, pts.max(0) + 5.0
    w, h = hi - lo
    lines = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{w:.1f}mm" height="{h:.1f}mm" '
             f'viewBox="0 0 {w:.1f} {h:.1f}">']
    for kind, poly in net:
        d = " ".join(f"{x - lo[0]:.2f},{hi[1] - y:.2f}" for x, y in poly)
        dash = ' stroke-dasharray="2,1"' if kind == "fold" else ""
        lines.append(f'<polyline points="{d}" fill="none" stroke="black" '
                     f'stroke-width="0.2"{dash}/>')
    lines.append(f'<text x="2" y="4" font-size="3">{stand.label} ({stand.part}): cut solid '
                 "lines, fold dashed, glue the tab; top and base close the box</text>")
    return "\n".join(lines + ["</svg>", ""])


def write_stand_files(stands, folder: Path, *, step: bool = True) -> list[Path]:
    """Write each stand as ``<label>.stl`` (world millimetres, its base where it goes),
    ``<label>.step`` (CadQuery; skipped when ``step`` is False) and ``<label>-card.svg``
    (the card net, 1:1 millimetres) into ``folder``; returns the paths written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for stand in stands:
        mesh = stand.mesh()
        mesh.apply_scale(1000.0)
        path = folder / f"{stand.label}.stl"
        mesh.export(path)
        written.append(path)
        if step:
            import cadquery as cq

            path = folder / f"{stand.label}.step"
            cq.exporters.export(stand_solid(stand), str(path))
            written.append(path)
        path = folder / f"{stand.label}-card.svg"
        path.write_text(_net_svg(stand), encoding="utf-8")
        written.append(path)
    return written
