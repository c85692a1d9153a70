"""amorgs.problems.cr3bp."""
