"""robocal.io."""
