"""Stage 6, printing: tiled 1:1 assembly templates (PDF and SVG) with AprilTag marks, and the
check of a printed sheet from a scan or photo.

Modules, in the order a template is made: :mod:`~rgmcad.printing.inputs` (posed parts and
base planes of a scene, placement order, tolerance notes), :mod:`~rgmcad.printing.plane`
(the plane drawn on), :mod:`~rgmcad.printing.labels` and :mod:`~rgmcad.printing.drawing`
(silhouettes, labels, reference lines), :mod:`~rgmcad.printing.sheets` (paper, sheets, marks
and their ids), :mod:`~rgmcad.printing.tiling` (the sheet grid), :mod:`~rgmcad.printing.seams`
(where sheets meet: seam lines, kept areas, matching marks), :mod:`~rgmcad.printing.pdf`,
:mod:`~rgmcad.printing.sheetpage` and :mod:`~rgmcad.printing.svg` (the writers),
:mod:`~rgmcad.printing.template` (the entry point,
:func:`~rgmcad.printing.template.make_template`); :mod:`~rgmcad.printing.check` reads a
printed sheet back (:mod:`~rgmcad.printing.marks` finds its marks,
:mod:`~rgmcad.printing.edges` its paper's edges).
"""
