"""amorgs.ablation."""
