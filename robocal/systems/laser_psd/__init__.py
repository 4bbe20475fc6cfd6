"""robocal.systems.laser_psd."""
