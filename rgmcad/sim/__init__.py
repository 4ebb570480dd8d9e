"""Stage 3, simulation: the pybullet world built from a scene, event conditions, the causal
monitor, the exact validity test, one simulation run, and rendering."""
