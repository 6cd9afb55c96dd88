"""Files: readers and writers registered by (product, extension), atomic writes and
output folders.  Every ``_*.py`` module of this package is imported on start, so a new
file format is one new module that registers its reader or writer.

Products: ``heightmap`` (``heightmap.exr``), ``measured`` (measured height maps: X3P, EXR,
npy/npz and instrument formats), ``profile`` (measured profiles: text exports, Dektak
``.opdx``, X3P PRF), ``toolpath`` and ``program`` (machine programs: npz, csv,
nc), ``frames`` (``interferogram.exr``; TIFF / PNG stacks with a settings JSON),
``measurement`` (``height.exr``).  :func:`reader` / :func:`writer` look them up.
"""

from ._atomic import (
                      MARKER,
                      atomic_output_dir,
                      atomic_write_bytes,
                      atomic_write_stream,
                      atomic_write_text,
                      check_output_dir,
                      check_output_path,
                      MARKER_VERSION,
                      claim_output_dir,
                      completed_outputs,
                      json_safe,
                      open_lock_file,
                      read_marker,
                      refuse_inputs_inside,
                      scene_files,
                      write_json,
                      write_marker,
)
from ._discard import discard_unused, discarding_new_folder
from ._special import not_a_file
from ._exr import exr_placement, read_exr, write_exr
from ._frames import FRAME_CHANNELS, read_frames_exr, write_frames_exr
from ._heightmap import heightmap_attrs, read_heightmap_exr, write_heightmap_exr
from ._limits import (
                      check_exr,
                      check_npy,
                      check_npz,
                      check_real_array,
                      check_x3p,
                      check_frames,
                      check_zip,
                      per_value_bytes,
                      read_json_file,
                      reading_for,
)
from ._measured import (UNIT_TO_MM, MeasuredMap, measured_formats, read_measured, read_surface,
                        reader_for)
from ._png import png_bytes_with_text, save_png
from ._profile import MeasuredProfile, is_profile_file, read_profile
from ._pyramid import block_sums, coarsen, level_count, means, preview
from ._registry import formats, reader, register_reader, register_writer, writer
from ._stack import STACK_EXTENSIONS, read_frame_stack, write_measurement_exr
from ._toolpath import (
                      CSV_COLUMNS,
                      PROGRAM_CSV_COLUMNS,
                      export_program,
                      program_formats,
                      nc_comment_text,
                      COMMENT_STYLES,
                      check_nc_style,
                      cut_points,
                      program_axes,
                      program_blocks,
                      read_csv,
                      read_nc_blocks,
                      read_nc,
                      read_program_nc,
                      read_toolpath_npz,
                      write_csv,
                      write_nc,
                      write_program_csv,
                      write_program_nc,
                      write_program_npz,
                      write_toolpath_npz,
)
from ._tables import table_csv
from ._program import ImportedProgram, program_dialect, read_program
from ..core.programs import register_program_reader
from ._program_scan import scan_program
from ._vendor import read_nms, read_tmd, read_x3p_plain
from ._x3p import read_x3p, read_x3p_xy, write_x3p
from ._zarr import ZarrHeightMap, check_store_tree, chunk_files, create_heightmap_zarr, set_store_attrs
from ._exr import heightmap_channels, heightmap_overview
from ._heightmap import grid_attrs
from ._file_record import file_record
from ..core.plugins import import_private_modules

# the processes read [process] program files through core (they do not import io)
register_program_reader(read_program)

# file formats added as modules of this package register themselves on import
import_private_modules(__name__, __path__, skip=("_registry", "_atomic", "_limits"))

__all__ = ["file_record", "discard_unused", "discarding_new_folder", "not_a_file", "atomic_output_dir", "atomic_write_bytes", "atomic_write_text", "atomic_write_stream",
           "check_output_path", "check_output_dir", "refuse_inputs_inside", "scene_files", "claim_output_dir", "read_marker", "write_marker", "MARKER",
           "write_json", "json_safe", "open_lock_file",
           "read_exr", "write_exr", "save_png", "png_bytes_with_text", "read_x3p", "write_x3p",
           "read_measured", "measured_formats", "read_frames_exr", "write_frames_exr",
           "FRAME_CHANNELS", "read_frame_stack", "write_measurement_exr", "STACK_EXTENSIONS",
           "read_heightmap_exr", "write_heightmap_exr", "heightmap_attrs",
           "formats", "reader", "writer", "register_reader", "register_writer",
           "export_program", "program_formats", "nc_comment_text", "COMMENT_STYLES",
           "check_nc_style", "read_csv", "read_nc", "read_program_nc", "write_csv", "write_nc",
           "read_toolpath_npz", "write_toolpath_npz", "write_program_csv", "write_program_nc",
           "write_program_npz", "CSV_COLUMNS", "PROGRAM_CSV_COLUMNS", "check_exr", "check_npy",
           "check_npz", "check_real_array", "check_x3p", "check_zip", "read_json_file",
           "exr_placement", "block_sums", "coarsen", "level_count", "means", "preview",
           "ZarrHeightMap", "check_store_tree", "chunk_files", "create_heightmap_zarr", "set_store_attrs", "heightmap_overview", "heightmap_channels",
           "grid_attrs", "table_csv",
           "read_x3p_xy", "MeasuredMap", "UNIT_TO_MM", "read_surface", "reader_for", "read_tmd",
           "read_nms", "read_x3p_plain", "completed_outputs", "open_lock_file", "MARKER_VERSION",
           "reading_for", "per_value_bytes", "check_frames", "read_nc_blocks", "program_blocks", "cut_points",
           "program_axes", "MeasuredProfile", "read_profile", "is_profile_file",
           "read_program", "ImportedProgram", "program_dialect", "scan_program"]
