"""Visual checks: the scene file, the meshcat view, plots and the HTML report.

meshcat and matplotlib are optional (`pip install robocal[viz]`): the names that need them are
loaded on first use (PEP 562 `__getattr__`), so `robocal.viz.scene` works on a core install.
"""
from importlib import import_module

_LAZY = {
    "SceneView": "robocal.viz.meshcat_check", "write_static_html": "robocal.viz.meshcat_check",
    "RecordingWindow": "robocal.viz.meshcat_page",
    "arrows": "robocal.viz.shapes", "colour_scale": "robocal.viz.shapes", "nice_factor": "robocal.viz.shapes",
    "write_report": "robocal.viz.report",
}
__all__ = sorted(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        return getattr(import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'robocal.viz' has no attribute {name!r}")
