"""The machines of the source documents, each a subpackage with its mechanism and its workflow:
stewart (docs/stewart_calibration.md), laser_psd (docs/laser_psd.md), floating_nut (docs/floating_nut_hexapod.md),
pcmm (docs/pcmm_calibration.md). Force-regulated path following lives in robocal.dynamics."""
