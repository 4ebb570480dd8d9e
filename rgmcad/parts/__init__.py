"""Stage 1, parts: part families (typed parameters plus a CadQuery build), their registry, and
the builder that turns a family and parameters into meshes, CAD files and collision pieces."""
