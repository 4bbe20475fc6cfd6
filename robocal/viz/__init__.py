"""Visual checks: the scene file, the meshcat view, plots and the HTML report.

meshcat and matplotlib are optional (`pip install robocal[viz]`): every name is loaded on first use, so
`robocal.viz.scene` works on a core install.
"""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "shapes": "arrows colour_scale nice_factor", "scene": "read_scene scene_bytes",
    "meshcat_page": "RecordingWindow", "meshcat_check": "SceneView write_static_html", "report": "write_report"})
