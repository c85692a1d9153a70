"""amorgs.models."""
