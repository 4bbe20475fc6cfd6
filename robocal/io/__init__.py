"""Files on disk, knowing no robot: CSV tables, YAML and text files, number formatting, output folders
written whole with a manifest, camera targets and detections, generated blocks of docs pages."""
from robocal.io.camera_target import CameraTarget, target_from_dict
from robocal.io.detections import Detections, read_detections, write_detections
from robocal.io.doc_blocks import page_differences, update_page
from robocal.io.output_folder import check_replaceable, write_folder
from robocal.io.tables import Table, read_csv, write_csv
from robocal.io.text_files import format_number, format_numbers, write_atomic
from robocal.io.yaml_files import read_yaml

__all__ = ["CameraTarget", "target_from_dict", "Detections", "read_detections", "write_detections",
           "page_differences", "update_page", "check_replaceable", "write_folder", "Table", "read_csv", "write_csv",
           "format_number", "format_numbers", "write_atomic", "read_yaml"]
