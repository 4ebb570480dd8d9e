"""Stage 6, printing: tiled 1:1 assembly templates (PDF and SVG) with AprilTag marks, and the
check of a printed sheet from a scan or photo."""
