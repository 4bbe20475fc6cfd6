"""robocal.systems.pcmm."""
