"""amorgs.solvers."""
