"""robocal.systems.stewart."""
