"""amorgs.figures."""
