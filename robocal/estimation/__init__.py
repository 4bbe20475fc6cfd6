"""robocal.estimation."""
