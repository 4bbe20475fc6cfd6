"""robocal.model."""
