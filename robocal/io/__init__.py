"""Files on disk, knowing no robot: CSV tables, YAML and text files, number formatting, output folders
written whole with a manifest."""
from robocal.io.doc_blocks import page_differences, update_page
from robocal.io.output_folder import check_replaceable, write_folder
from robocal.io.tables import Table, read_csv, write_csv
from robocal.io.text_files import format_number, format_numbers, write_atomic
from robocal.io.yaml_files import read_yaml

__all__ = ["check_replaceable", "write_folder", "Table", "read_csv", "write_csv", "format_number", "format_numbers",
           "write_atomic", "read_yaml", "page_differences", "update_page"]
