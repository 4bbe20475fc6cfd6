"""Files in and out: the config, CSV tables, the calibrated URDF, output folders, number formatting."""
from robocal.io.lazy_exports import lazy_exports

__getattr__, __all__ = lazy_exports(__name__, {
    "urdf_export": "calibrated_urdf export_urdf", "text_files": "format_number format_numbers write_atomic",
    "config": "load_config Setup setup_from_config", "tables": "read_csv Table write_csv",
    "output": "write_results"})
