"""The robocal plugin provides the fixtures (entry point `robocal`, or `-p robocal.testing.pytest_plugin`)."""
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")   # small dense algebra: threads only slow it down
