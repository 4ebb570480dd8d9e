"""Stage 3, simulation: the physics engine (a pybullet client of one's own), collision
shapes and mass properties of parts, the pybullet world built from a scene, event
conditions, the causal monitor, the exact validity test, one simulation run, and rendering."""
