"""robocal.systems."""
