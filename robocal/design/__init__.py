"""robocal.design.selection."""
