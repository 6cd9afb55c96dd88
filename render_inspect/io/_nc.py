"""NC programs in the two dialects the project writes (:mod:`render_inspect.io._toolpath`
describes both): writing a turning :class:`ToolPath` or a sculpturing
:class:`LinearProgram` with its :class:`Links`, reading the cutting path back, and
reading every block as written (:func:`read_nc_blocks`, what the program verifier
checks).  :func:`program_blocks` builds the same blocks in memory without a file.

The dialects (their words, sections, axes, moves and the blocks built in memory) are in
:mod:`._nc_dialect`, the writers in :mod:`._nc_write`, the readers in :mod:`._nc_parse`;
this module gathers them."""

from __future__ import annotations

from ._nc_dialect import (CHUNK_ROWS, COMMENT_STYLES, check_nc_style, nc_comment_text,
                          program_axes, program_blocks)
from ._nc_parse import cut_points, read_nc, read_nc_blocks, read_program_nc
from ._nc_write import write_nc, write_program_nc

__all__ = ["write_nc", "read_nc", "write_program_nc", "read_program_nc", "read_nc_blocks",
           "program_blocks", "cut_points", "program_axes", "nc_comment_text", "CHUNK_ROWS",
           "COMMENT_STYLES", "check_nc_style"]
