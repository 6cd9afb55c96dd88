"""File formats and atomic output folders."""

from ._atomic import atomic_output_dir, atomic_write_bytes, atomic_write_text, write_json
from ._exr import read_exr, write_exr
from ._measured import measured_formats, read_measured
from ._png import save_png, save_map_png
from ._x3p import read_x3p, write_x3p

__all__ = ["atomic_output_dir", "atomic_write_bytes", "atomic_write_text", "write_json",
           "read_exr", "write_exr", "save_png", "save_map_png",
           "read_x3p", "write_x3p", "read_measured", "measured_formats"]
