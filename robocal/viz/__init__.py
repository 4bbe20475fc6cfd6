"""Visual checks: the scene file, the meshcat view, plots and the HTML report.

meshcat and matplotlib are the optional [viz] extra: the scene file works on a core install, and the names
built on the extra are imported on first use (PEP 562), so `import robocal.viz` never needs it."""
from importlib import import_module

from robocal.viz.scene import read_scene, scene_bytes

__all__ = ["read_scene", "scene_bytes"]

#: names that need the [viz] extra, and the module of each
OPTIONAL = {"arrows": "shapes", "colour_scale": "shapes", "nice_factor": "shapes", "RecordingWindow": "meshcat_page",
            "SceneView": "meshcat_check", "write_static_html": "meshcat_check", "write_report": "report"}
__all__ += sorted(OPTIONAL)


def __getattr__(name):
    if name in OPTIONAL:    # meshcat / matplotlib only when such a name is asked for
        return getattr(import_module(f"robocal.viz.{OPTIONAL[name]}"), name)
    raise AttributeError(f"module 'robocal.viz' has no attribute {name!r}")
