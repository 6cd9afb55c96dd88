"""File formats and atomic output folders."""

from ._atomic import atomic_output_dir, atomic_write_bytes, atomic_write_text, write_json
from ._exr import read_exr, write_exr
from ._measured import (UNIT_TO_MM, MeasuredMap, measured_formats, read_measured, read_surface,
                        reader_for)
from ._png import save_height_png, save_map_png, save_png
from ._vendor import read_nms, read_tmd, read_x3p_plain
from ._x3p import read_x3p, read_x3p_xy, write_x3p

__all__ = ["atomic_output_dir", "atomic_write_bytes", "atomic_write_text", "write_json",
           "read_exr", "write_exr", "save_png", "save_map_png", "save_height_png",
           "read_x3p", "read_x3p_xy", "write_x3p", "read_measured", "measured_formats",
           "MeasuredMap", "UNIT_TO_MM", "read_surface", "reader_for", "read_tmd", "read_nms",
           "read_x3p_plain"]
