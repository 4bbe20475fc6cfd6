"""robocal.systems.floating_nut."""
