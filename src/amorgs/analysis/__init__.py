"""amorgs.analysis."""
