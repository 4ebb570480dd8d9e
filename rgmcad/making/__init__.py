"""Between the printed template and a working machine: supports, bill of materials, steps."""
