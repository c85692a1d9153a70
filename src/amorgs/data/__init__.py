"""amorgs.data."""
