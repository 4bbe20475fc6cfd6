"""Files in and out: the config, CSV tables, the calibrated URDF, output folders, number formatting."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "config": "Setup load_config setup_from_config", "tables": "Table read_csv write_csv",
    "urdf_export": "calibrated_urdf export_urdf", "output": "write_results",
    "text_files": "format_number format_numbers write_atomic"})
